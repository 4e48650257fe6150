"""training/goal_hold.py: a Cartesian velocity zeroed while the object is within the radius
of its goal, the width passed through, the policy acting again outside; bad settings
refused by name; and in the env, the hand held still at the goal."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from franka_sim_gym.training.goal_hold import GoalHold
from tests.scripted_policies import Fixed


def observations(offsets) -> dict:
    """One row per offset [m] of the achieved goal from a desired goal at (0.5, 0, 0.02)."""
    desired = np.tile([0.5, 0.0, 0.02], (len(offsets), 1)).astype(np.float32)
    achieved = desired + np.asarray(offsets, dtype=np.float32)
    observation = np.zeros((len(offsets), 36), dtype=np.float32)
    return {"observation": observation, "achieved_goal": achieved, "desired_goal": desired}


def test_the_velocity_is_zero_within_the_radius_and_the_policys_outside():
    hold = GoalHold(Fixed([0.4, -0.2, 0.1]), radius=0.03)
    offsets = [[0.0, 0.0, 0.0], [0.029, 0.0, 0.0], [0.02, 0.0221, 0.0], [0.0, 0.031, 0.0]]
    held, _ = hold.predict(observations(offsets))
    # |(0.02, 0.0221)| = 0.0298 is inside; 0.031 is not
    np.testing.assert_array_equal(held[:3], 0.0)
    np.testing.assert_allclose(held[3], [0.4, -0.2, 0.1])
    assert held.dtype == np.float32


def test_the_width_passes_through_and_a_twist_of_six_is_zeroed_whole():
    width = GoalHold(Fixed([0.4, -0.2, 0.1, -1.0]), radius=0.03)  # (x, y, z, width)
    held, _ = width.predict(observations([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]))
    np.testing.assert_allclose(held, [[0, 0, 0, -1.0], [0.4, -0.2, 0.1, -1.0]])
    six = GoalHold(Fixed([0.1] * 6 + [0.5]), radius=0.03, velocity_dims=6)
    held, _ = six.predict(observations([[0.0, 0.0, 0.01]]))
    np.testing.assert_allclose(held, [[0.0] * 6 + [0.5]])


def test_one_observation_as_sb3_gives_it():
    one = {k: v[0] for k, v in observations([[0.01, 0.0, 0.0]]).items()}
    held, _ = GoalHold(Fixed([0.4, -0.2, 0.1]), radius=0.03).predict(one)
    np.testing.assert_array_equal(held, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("radius", [0.0, -0.01, float("nan"), float("inf")])
def test_a_radius_that_is_not_a_positive_distance_is_refused(radius):
    with pytest.raises(ValueError, match="radius must be a positive distance"):
        GoalHold(Fixed([0, 0, 0]), radius=radius)


def test_velocity_dims_other_than_a_twists_are_refused():
    with pytest.raises(ValueError, match="velocity_dims must be 3 or 6, got 4"):
        GoalHold(Fixed([0, 0, 0]), radius=0.03, velocity_dims=4)


def test_on_push_a_block_on_its_goal_holds_the_hand_still():
    """Push with the policy's goal on the block: the held policy commands a zero twist and
    the TCP stays where it was; the same policy unheld drives it off (0.12 m/s)."""
    moved = {}
    for radius in (0.03, None):
        env = gym.make("FrankaFCIPush-v0")
        obs, _ = env.reset(seed=2)
        start = obs["observation"][14:17].copy()
        policy = Fixed([0.4, 0.0, 0.0])
        policy = policy if radius is None else GoalHold(policy, radius=radius)
        for _ in range(5):
            obs["desired_goal"] = obs["achieved_goal"].copy()  # the policy's view: done
            action, _ = policy.predict({k: v[None] for k, v in obs.items()})
            obs, *_ = env.step(action[0])
        moved[radius] = float(np.linalg.norm(obs["observation"][14:17] - start))
        env.close()
    assert moved[0.03] < 1e-4 and moved[None] > 0.01, moved
