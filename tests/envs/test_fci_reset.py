"""reset_mode="fci": a reset a real robot could do (StopMove, AutomaticErrorRecovery after a
reflex, a joint-position motion to the start pose judged by the robot's own checks)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.fci_reset import (
    HOME_ACCELERATION,
    HOME_JERK,
    HOME_VELOCITY,
    home_duration,
    quintic,
)


def test_fci_reset_reaches_the_teleport_reset_start_pose_through_a_joint_motion():
    teleport = gym.make("FrankaFCI-v0")
    fci = gym.make("FrankaFCI-v0", reset_mode="fci")
    obs_t, _ = teleport.reset(seed=3)
    ids_before = int(fci.unwrapped.controller.states["message_id"][0])
    obs_f, info = fci.reset(seed=3)
    q_t = teleport.unwrapped.controller.physics.q[0]
    q_f = fci.unwrapped.controller.physics.q[0]
    assert np.abs(q_f - q_t).max() < 1e-4  # the same drawn start, reached by the servo
    np.testing.assert_array_equal(obs_f["desired_goal"], obs_t["desired_goal"])
    # It took cycles the robot published (the move home and the settling), not a teleport.
    assert int(fci.unwrapped.controller.states["message_id"][0]) - ids_before > 100
    assert info["robot_mode"] == "kMove" and info["errors"] == () and info["reflex_reason"] == ()


def test_fci_reset_after_a_reflex_recovers_and_the_next_episode_runs():
    env = gym.make("FrankaFCI-v0", reset_mode="fci", action_filter="none")
    env.reset(seed=0)
    for _ in range(5):  # a naive client's held target: the robot aborts within a few steps
        _, _, terminated, _, info = env.step(np.full(7, 0.9, np.float32))
        if terminated:
            break
    assert terminated and info["reflex_reason"] == (
        "joint_motion_generator_velocity_discontinuity",
    )
    assert info["robot_mode"] == "kReflex"
    _, info = env.reset(seed=1)
    assert info["errors"] == () and info["reflex_reason"] == () and info["robot_mode"] == "kMove"
    _, _, terminated, _, info = env.step(np.zeros(7, np.float32))
    assert not terminated and info["errors"] == ()


def test_fci_reset_keeps_the_configured_frames_a_teleport_clears_them():
    ne_t_ee = np.eye(4)
    ne_t_ee[2, 3] = 0.1  # 10 cm along the flange's z
    wire = ne_t_ee.T.reshape(16)  # column-major, as the state carries it
    for mode, kept in (("fci", True), ("teleport", False)):
        env = gym.make("FrankaFCI-v0", reset_mode=mode)
        env.reset(seed=0)
        env.unwrapped.controller.stop_move(0)
        env.unwrapped.controller.set_ne_to_ee(0, wire)
        env.reset(seed=1)
        reported = env.unwrapped.controller.states["NE_T_EE"][0]
        assert np.allclose(reported, wire) == kept, mode


def test_fci_reset_is_deterministic():
    runs = []
    for _ in range(2):
        env = gym.make("FrankaFCI-v0", reset_mode="fci")
        obs, _ = env.reset(seed=7)
        trace = [obs["observation"].copy()]
        for k in range(3):
            obs, *_ = env.step(np.full(7, 0.3 * (-1) ** k, np.float32))
            trace.append(obs["observation"].copy())
        obs, _ = env.reset()
        trace.append(obs["observation"].copy())
        runs.append(np.stack(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_fci_reset_mode_needs_one_arm_per_world_and_a_known_name():
    with pytest.raises(ValueError, match="reset_mode='fci' needs one arm per world, got 4"):
        gym.make_vec(
            "FrankaFCI-v0", num_envs=4, vectorization_mode="vector_entry_point", reset_mode="fci"
        )
    with pytest.raises(ValueError, match="unknown reset_mode 'warp'"):
        gym.make("FrankaFCI-v0", reset_mode="warp")


@pytest.mark.parametrize("distance", [1e-4, 0.05, 0.5, 2.0, 5.8])
def test_the_move_home_stays_inside_its_velocity_acceleration_and_jerk(distance):
    steps = round(home_duration(distance) * 1000)
    q = distance * quintic(np.arange(steps + 1) / steps)
    dq = np.diff(q) / 1e-3
    ddq = np.diff(dq) / 1e-3
    dddq = np.diff(ddq) / 1e-3
    assert q[0] == 0.0 and q[-1] == pytest.approx(distance, abs=1e-12)
    assert np.abs(dq).max() <= HOME_VELOCITY
    assert np.abs(ddq).max() <= HOME_ACCELERATION * 1.01  # the sampled peak, 1 % slack
    assert np.abs(dddq).max() <= HOME_JERK * 1.05
