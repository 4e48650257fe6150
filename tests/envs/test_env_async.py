"""The env's ``joint_position_async`` interface: libfranka's asynchronous joint-position
control, the robot's own generator moving to each step's target (docs/motion-limits.md
"The asynchronous generator")."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import franka_sim_gym  # noqa: F401 (registers the ids)
from franka_sim_gym.envs.commands import ActionScale, move_options
from franka_sim_gym.fci.tables import FR3

ID = "FrankaFCIJointPositionAsync-v0"


def test_the_id_starts_an_asynchronous_move_with_the_nameplate_velocities():
    env = gym.make(ID)
    env.reset(seed=1)
    ctrl = env.unwrapped.controller
    assert ctrl.asynchronous.active[0]
    # The nameplate caps, less the generator's margin inside the envelope (0.011 rad/s).
    np.testing.assert_allclose(ctrl.asynchronous.vmax[0], FR3.dq_max - 0.011)
    assert move_options("joint_position", FR3) == {}
    caps = move_options("joint_position_async", FR3, ActionScale(async_max_velocity=(0.5,) * 7))
    assert caps == {"use_async_motion_generator": True, "maximum_velocity": (0.5,) * 7}
    env.close()


def test_a_held_action_reaches_its_target_without_a_violation():
    env = gym.make(ID, max_episode_steps=100)
    env.reset(seed=2)
    ctrl = env.unwrapped.controller
    q0 = ctrl.states["q_d"][0].astype(float).copy()
    action = np.full(7, 0.5, dtype=np.float32)
    _, _, terminated, _, info = env.step(action)  # the target: q_d + 0.05 rad per joint
    target = q0 + 0.05  # docs/env.md: a target 0.1 rad (at action 1) from the step's q_d
    np.testing.assert_allclose(ctrl.asynchronous.target[0], target, atol=1e-6)
    for _ in range(20):  # zero actions: each step's target is where q_d then is
        q_d = ctrl.states["q_d"][0].astype(float).copy()
        moving = np.abs(ctrl.states["dq_d"][0]).max() > 0.01
        _, _, terminated, _, info = env.step(np.zeros(7, dtype=np.float32))
        assert not terminated and info["violations"] == ()
        if moving:  # (q_d, not the lagging measured q)
            np.testing.assert_array_equal(ctrl.asynchronous.target[0], q_d)
    assert np.abs(ctrl.states["dq_d"][0]).max() < 0.01
    assert info["control_command_success_rate"] == 1.0
    env.close()


def test_a_lossy_link_loses_targets_not_cycles():
    env = gym.make(ID, channel="loss:0.5", enforce_comm_constraints=True)
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    for _ in range(20):
        _, _, terminated, _, info = env.step(rng.uniform(-1, 1, 7).astype(np.float32))
        assert not terminated, info
        assert info["lost_cycles"] == 0 and info["longest_lost_run"] == 0
    env.close()
