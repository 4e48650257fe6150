"""The env's Cartesian action interfaces: what the client sends, what the robot refuses.

The env plays a libfranka Cartesian client (envs/commands.py): O_T_EE_c or O_dP_EE_c
per cycle, filtered by libfranka's cartesianLowpassFilter and Cartesian limitRate. The
robot judges both the Cartesian stream and, for a pose, its IK joint trajectory
(docs/fci-behaviour.md "The joint side of a Cartesian command").
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.commands import CARTESIAN_LIMITS, CommandGenerator
from franka_sim_gym.fci.frames import from_wire, is_homogeneous
from franka_sim_gym.fci.tables import FER, FR3
from franka_sim_gym.sim.rotations import rotation_log

IDS = ("FrankaFCICartesianPose-v0", "FrankaFCICartesianVelocity-v0")


def random_episodes(env, episodes: int, seed: int = 0):
    """Uniform random actions; returns (reflex reasons, violations seen, steps)."""
    rng = np.random.default_rng(seed)
    reasons, violations, steps = [], set(), 0
    for ep in range(episodes):
        env.reset(seed=seed + ep)
        done = False
        while not done:
            a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            _, _, terminated, truncated, info = env.step(a)
            violations.update(info["violations"])
            steps += 1
            done = terminated or truncated
            if terminated:
                reasons.append(info["reflex_reason"])
    return reasons, violations, steps


@pytest.mark.parametrize("env_id", IDS)
def test_random_actions_through_the_conservative_limiter_trip_nothing(env_id):
    env = gym.make(env_id, max_episode_steps=25)
    reasons, violations, steps = random_episodes(env, 6)
    assert steps == 6 * 25
    assert reasons == [] and violations == set()


@pytest.mark.parametrize(
    ("env_id", "expected"),
    [
        ("FrankaFCICartesianPose-v0", "cartesian_motion_generator_velocity_discontinuity"),
        ("FrankaFCICartesianVelocity-v0", "cartesian_motion_generator_acceleration_discontinuity"),
    ],
)
def test_a_held_cartesian_target_trips_the_interface_relative_discontinuity(env_id, expected):
    """A pose target 5 cm away held for every cycle is a step in position (an acceleration
    limit: "velocity_discontinuity" on a pose interface); a held twist of 0.3 m/s is a step
    in velocity (its jerk: "acceleration_discontinuity" on a velocity interface)."""
    env = gym.make(env_id, action_filter="none", cartesian_dof=3)
    env.reset(seed=1)
    env.step(np.zeros(3, np.float32))  # the motion's first command: where it starts
    _, reward, terminated, _, info = env.step(np.array([1.0, 0.0, 0.0], np.float32))
    assert terminated
    assert info["reflex_reason"] == (expected,)
    assert info["robot_mode"] == "kReflex"


def test_libfrankas_own_cartesian_limits_trip_the_joint_side():
    """libfranka's Cartesian limitRate keeps the Cartesian stream legal, but at 9 m/s^2 the
    IK joint trajectory exceeds the robot's 10 rad/s^2: 29 (and 30) end the episode, as on a
    real arm; the conservative limits reach the same target without a reflex."""
    action = np.array([1.0, 0.0, -1.0], np.float32)
    env = gym.make("FrankaFCICartesianPose-v0", cartesian_dof=3, cartesian_limits="libfranka")
    env.reset(seed=2)
    for _ in range(10):
        _, _, terminated, _, info = env.step(action)
        if terminated:
            break
    assert terminated
    assert "cartesian_motion_generator_joint_velocity_discontinuity" in info["reflex_reason"]
    # The Cartesian rows themselves never fired: only the joint side did.
    assert all("joint" in name for name in info["reflex_reason"])
    safe = gym.make("FrankaFCICartesianPose-v0", cartesian_dof=3)
    safe.reset(seed=2)
    for _ in range(10):
        _, _, terminated, _, info = safe.step(action)
        assert not terminated and info["violations"] == ()


@pytest.mark.parametrize(
    "action_filter", ["limit_rate", "lowpass", "interpolate", "interpolate_limit_rate"]
)
def test_three_dof_actions_hold_the_orientation(action_filter):
    env = gym.make(
        "FrankaFCICartesianPose-v0",
        cartesian_dof=3,
        action_filter=action_filter,
        enforce_motion_limits=False,
    )
    assert env.action_space.shape == (3,)
    env.reset(seed=4)
    R0 = from_wire(env.unwrapped.controller.states["O_T_EE_c"][0])[:3, :3]
    p0 = env.unwrapped.controller.writer.O_T_EE[0, 12:15].copy()
    for _ in range(5):  # 5 x 1 cm per axis
        env.step(np.array([0.2, -0.2, 0.2], np.float32))
    env.step(np.zeros(3, np.float32))
    state = env.unwrapped.controller.states[0]
    R = from_wire(state["O_T_EE_c"])[:3, :3]
    assert np.linalg.norm(rotation_log(R @ R0.T)) < 1e-5
    moved = env.unwrapped.controller.writer.O_T_EE[0, 12:15] - p0
    if action_filter.endswith("limit_rate"):  # 1.5 m/s^2 for 0.24 s: a few cm, straight
        assert moved[0] > 0.01 and moved[1] < -0.01 and moved[2] > 0.01
        np.testing.assert_allclose(moved / moved[0], [1, -1, 1], atol=0.05)
    else:  # the targets are reached
        np.testing.assert_allclose(moved, [0.05, -0.05, 0.05], atol=0.01)


def test_six_dof_actions_turn_the_end_effector():
    env = gym.make("FrankaFCICartesianPose-v0", enforce_motion_limits=False)
    assert env.action_space.shape == (6,)
    env.reset(seed=5)
    R0 = from_wire(env.unwrapped.controller.states["O_T_EE_c"][0])[:3, :3]
    for _ in range(15):
        env.step(np.array([0, 0, 0, 0, 0, 1.0], np.float32))
    R = from_wire(env.unwrapped.controller.states["O_T_EE_c"][0])[:3, :3]
    turn = rotation_log(R @ R0.T)
    assert turn[2] > 0.1 and abs(turn[0]) < 1e-3 and abs(turn[1]) < 1e-3


def test_every_pose_the_client_sends_is_a_homogeneous_transform(monkeypatch):
    """The step's reference comes from the float32 state; the client re-orthonormalises it
    so libfranka's isHomogeneousTransformation (1e-5) never refuses a command. Every
    command the env sends over five steps is recorded and checked to 1e-9."""
    env = gym.make("FrankaFCICartesianPose-v0", action_filter="limit_rate")
    env.reset(seed=6)
    gen = env.unwrapped.commands
    sent, command = [], gen.command

    def recording(*args, **kwargs):
        out = command(*args, **kwargs)
        sent.append(out.copy())
        return out

    monkeypatch.setattr(gen, "command", recording)
    rng = np.random.default_rng(6)
    for _ in range(5):
        env.step(rng.uniform(-1, 1, 6).astype(np.float32))
    assert len(sent) == 5 * 40
    assert is_homogeneous(from_wire(np.concatenate(sent)), 1e-9).all()


def test_bad_cartesian_arguments_are_clear_errors():
    with pytest.raises(ValueError, match="cartesian_dof must be 3 or 6"):
        gym.make("FrankaFCICartesianPose-v0", cartesian_dof=4)
    with pytest.raises(ValueError, match="cartesian_limits must be one of"):
        gym.make("FrankaFCICartesianVelocity-v0", cartesian_limits="fast")
    with pytest.raises(ValueError, match="cartesian_limits must be one of"):
        CommandGenerator("cartesian_pose", "limit_rate", 40, cartesian_limits=(1.0, 2.0))
    assert set(CARTESIAN_LIMITS) == {"libfranka", "conservative"}
    # "libfranka" is the robot's own rate_limiting.h targets, per robot table.
    for table in (FR3, FER):
        gen = CommandGenerator(
            "cartesian_velocity", "limit_rate", 40, table, cartesian_limits="libfranka"
        )
        assert gen.cartesian_limits == (
            table.v_trans_max,
            table.a_trans_max,
            table.j_trans_max,
            table.v_rot_max,
            table.a_rot_max,
            table.j_rot_max,
        )
    assert FR3.v_trans_max == 3.0 - 1e-3 and FER.v_trans_max == 1.7 - 1e-3
    # Six numbers, as a tuple or as the list JSON gives (train_config.json).
    listed = CommandGenerator("cartesian_velocity", "limit_rate", 40, cartesian_limits=[1] * 6)
    assert listed.cartesian_limits == (1.0,) * 6
