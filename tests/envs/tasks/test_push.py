"""Push: the block's reset, the goal, the reward and success rules, the reflex."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.tasks.push import CENTRE, HALF, RANGE, TABLE_HOME, Push
from franka_sim_gym.sim.arm import ArmPhysics

BLOCK = slice(23, 26)  # the block's position in Push's observation (no width entry)


def test_the_start_pose_puts_the_tcp_15_cm_above_the_table_pointing_down():
    physics = ArmPhysics(1, hand=True)
    physics.data.qpos[physics.layout.qpos_adr[0]] = TABLE_HOME
    mujoco.mj_forward(physics.model, physics.data)
    site = physics.layout.tcp_site[0]
    np.testing.assert_allclose(physics.data.site_xpos[site], [0.50, 0.0, 0.15], atol=1e-3)
    z_axis = physics.data.site_xmat[site].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(z_axis, [0, 0, -1], atol=1e-3)


def test_the_spaces_and_the_hand():
    env = gym.make("FrankaFCIPush-v0")
    assert env.spec.max_episode_steps == Push.max_episode_steps == 100
    assert env.action_space.shape == (3,)  # Cartesian velocity, translation only
    assert env.observation_space["observation"].shape == (23 + 13,)
    obs, _ = env.reset(seed=0)
    physics = env.unwrapped.controller.physics
    assert physics.finger_width()[0] == pytest.approx(0.0, abs=2e-4)  # closed
    for _ in range(3):
        env.step(np.zeros(3, np.float32))
    assert physics.finger_width()[0] == pytest.approx(0.0, abs=2e-4)  # and kept closed
    assert gym.make("FrankaFCIPushJointPosition-v0").action_space.shape == (7,)
    with pytest.raises(ValueError, match="gripper"):
        gym.make("FrankaFCIPush-v0", gripper=True)


def test_the_block_starts_seeded_at_rest_on_the_table_in_its_range():
    env = gym.make("FrankaFCIPush-v0")
    starts = []
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        block = obs["observation"][BLOCK]
        assert obs["achieved_goal"].tolist() == block.tolist()
        assert np.all(np.abs(block[:2] - CENTRE) <= RANGE + 1e-6)
        assert block[2] == pytest.approx(HALF, abs=1e-6)
        np.testing.assert_array_equal(obs["observation"][26:30], [1, 0, 0, 0])  # upright
        np.testing.assert_array_equal(obs["observation"][30:36], 0.0)  # at rest
        goal = obs["desired_goal"]
        assert np.all(np.abs(goal[:2] - CENTRE) <= RANGE + 1e-6) and goal[2] == pytest.approx(HALF)
        starts.append(block.tobytes())
    assert len(set(starts)) == 6
    again, _ = env.reset(seed=2)
    assert again["observation"][BLOCK].tobytes() == starts[2]
    # after a step the block rests where it was put (no drop, no drift)
    obs, *_ = env.step(np.zeros(3, np.float32))
    np.testing.assert_allclose(obs["observation"][BLOCK], again["observation"][BLOCK], atol=1e-4)


def test_reward_and_success_rules_vectorised():
    task = Push()
    goal = np.array([[0.5, 0.0, 0.02]] * 3)
    achieved = goal + np.array([[0.0, 0.0, 0.0], [0.049, 0.0, 0.0], [0.0, 0.06, 0.0]])
    assert task.is_success(achieved, goal).tolist() == [True, True, False]
    assert task.compute_reward(achieved, goal, None).tolist() == [0.0, 0.0, -1.0]
    dense = Push(reward_type="dense").compute_reward(achieved, goal, None)
    np.testing.assert_allclose(dense, [0.0, -0.049, -0.06], rtol=1e-6)
    charged = task.compute_reward(achieved, goal, {"reflex_penalty": np.array([0, -5.0, 0])})
    assert charged.tolist() == [0.0, -5.0, -1.0]
    with pytest.raises(ValueError, match="reward_type"):
        Push(reward_type="shaped")


def test_pushing_the_block_moves_the_achieved_goal_and_success_follows():
    env = gym.make("FrankaFCIPush-v0")
    obs, _ = env.reset(seed=0)
    physics = env.unwrapped.controller.physics
    adr = physics.layout.scene_qpos_adr["block"][0]
    goal = obs["desired_goal"]
    physics.data.qpos[adr : adr + 2] = goal[:2]  # the block put on the goal by hand
    obs, reward, terminated, _, info = env.step(np.zeros(3, np.float32))
    assert info["is_success"] and reward == 0.0 and not terminated
    np.testing.assert_allclose(obs["achieved_goal"][:2], goal[:2], atol=1e-3)


def test_a_descent_into_the_table_is_a_cartesian_reflex_and_charged():
    env = gym.make("FrankaFCIPush-v0")
    env.reset(seed=0)
    down = np.array([0.0, 0.0, -0.5], np.float32)
    step = 0
    while step < 60:
        _, reward, terminated, truncated, info = env.step(down)
        step += 1
        if terminated:
            break
    assert terminated and not truncated
    assert "cartesian_reflex" in info["reflex_reason"]
    assert info["reflex_penalty"] == -1.0 * (100 - step + 1)
    assert reward == pytest.approx(-1.0 + info["reflex_penalty"])
