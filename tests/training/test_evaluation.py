"""training/evaluation.py: N episodes side by side in the batched env, counted per arm."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.training.evaluation import evaluate
from tests.scripted_policies import POSE_STEPS, Still, TowardTheGoal

KWARGS = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 20}


def test_a_policy_that_reaches_scores_one_and_no_reflex():
    r = evaluate(TowardTheGoal(), "FrankaFCICartesianVelocity-v0", KWARGS, episodes=6, seed=0)
    assert r["success_rate"] == 1.0
    assert r["reflex_rate"] == 0.0 and r["reflexes_by_error"] == {}
    assert r["link_success_rate"] == 1.0  # a perfect channel answers every cycle


def test_small_pose_steps_reach_where_full_ones_overshoot_into_reflexes():
    """Cartesian pose targets near the reference reach every goal with no reflex; 5 cm
    targets every step make libfranka's pose limiter overshoot (docs/env.md), and the
    IK's joint velocity discontinuity (29) or the safety controller ends episodes."""
    pose = "FrankaFCICartesianPose-v0"
    r = evaluate(TowardTheGoal(**POSE_STEPS), pose, KWARGS, episodes=20, seed=0)
    assert r["success_rate"] == 1.0 and r["reflexes_by_error"] == {}
    r = evaluate(TowardTheGoal(), pose, KWARGS, episodes=20, seed=0)
    assert r["success_rate"] < 0.5 and r["reflex_rate"] > 0.0
    assert r["reflexes_by_error"]["cartesian_motion_generator_joint_velocity_discontinuity"] >= 1


def test_a_naive_policy_is_counted_by_the_robots_error_name():
    """Twists held unfiltered: every episode ends in the same named reflex."""
    kwargs = {**KWARGS, "action_filter": "none"}
    r = evaluate(TowardTheGoal(), "FrankaFCICartesianVelocity-v0", kwargs, episodes=4, seed=0)
    assert r["reflex_rate"] == 1.0 and r["success_rate"] == 0.0
    assert r["reflexes_by_error"] == {"cartesian_motion_generator_acceleration_discontinuity": 4}


def test_a_policy_that_stands_still_succeeds_only_where_the_goal_is_near():
    r = evaluate(Still(), "FrankaFCICartesianVelocity-v0", KWARGS, episodes=8, seed=0)
    assert r["reflex_rate"] == 0.0
    assert r["success_rate"] < 0.5


class Jerk:
    """Full twist from the first step: unfiltered, the robot refuses it at once."""

    def predict(self, obs, deterministic=True):
        return np.ones((len(obs["desired_goal"]), 3), np.float32), None


def test_an_episode_ending_in_a_reflex_is_no_success_even_inside_the_radius():
    """With a radius that holds every goal (Still succeeds everywhere), a reflex on the
    first cycle leaves the arm inside the radius: the env's is_success says so, the
    evaluation does not count it."""
    near = {**KWARGS, "distance_threshold": 10.0}
    still = evaluate(Still(), "FrankaFCICartesianVelocity-v0", near, episodes=16, seed=0)
    assert still["success_rate"] == 1.0
    kwargs = {**near, "action_filter": "none"}
    r = evaluate(Jerk(), "FrankaFCICartesianVelocity-v0", kwargs, episodes=16, seed=0)
    assert r["reflex_rate"] == 1.0
    assert r["success_rate"] == 0.0


def test_no_episode_is_a_clear_error():
    with pytest.raises(ValueError, match="episodes must be >= 1, got 0"):
        evaluate(Still(), "FrankaFCICartesianVelocity-v0", KWARGS, episodes=0, seed=0)
