"""PegInsertion: the peg in the hand at reset, the seeded fixture, success at full depth,
and force as the constraint."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.tasks.peg_insertion import (
    FIXTURE,
    FIXTURE_RANGE,
    HOLE_DEPTH,
    PegInsertion,
    tip_of,
)

EE, PEG = slice(14, 17), slice(23, 36)


def test_the_peg_is_held_in_the_hand_at_reset_and_stays_there():
    env = gym.make("FrankaFCIPegInsertion-v0")
    assert env.action_space.shape == (6,)  # Cartesian velocity with rotation
    obs, _ = env.reset(seed=0)
    physics = env.unwrapped.controller.physics
    width = physics.finger_width()[0]
    assert width == pytest.approx(0.02, abs=2e-4)  # closed on the 20 mm peg
    tip = obs["achieved_goal"]
    ee = obs["observation"][EE]
    assert np.linalg.norm(tip - ee) == pytest.approx(0.06, abs=1e-3)  # 60 mm below the TCP
    assert env.unwrapped.core.hands.load_configured[0]
    for _ in range(10):
        obs, _, terminated, _, _ = env.step(np.zeros(6, np.float32))
        assert not terminated
    assert env.unwrapped.controller.states[0]["m_load"] == pytest.approx(0.05)  # SetLoad
    np.testing.assert_allclose(obs["achieved_goal"], tip, atol=5e-4)  # no slip
    np.testing.assert_allclose(obs["observation"][EE], ee, atol=5e-4)


def test_the_fixture_is_seeded_within_2_cm_and_is_the_goal():
    env = gym.make("FrankaFCIPegInsertion-v0")
    physics = env.unwrapped.controller.physics
    body = physics.layout.scene_body["fixture"][0]
    goals = []
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        goal = obs["desired_goal"]
        assert np.all(np.abs(goal[:2] - FIXTURE[:2]) <= FIXTURE_RANGE + 1e-6) and goal[2] == 0
        np.testing.assert_allclose(physics.data.xpos[body], goal, atol=1e-6)  # it moved
        goals.append(goal.tobytes())
    assert len(set(goals)) == 5
    assert env.reset(seed=3)[0]["desired_goal"].tobytes() == goals[3]


def test_every_arm_of_a_batched_env_has_its_fixture_at_its_own_goal():
    envs = gym.make_vec("FrankaFCIPegInsertion-v0", num_envs=3,
                        vectorization_mode="vector_entry_point")  # fmt: skip
    physics = envs.unwrapped.core.controller.physics
    body = physics.layout.scene_body["fixture"][0]
    obs, _ = envs.reset(seed=7)
    goals = obs["desired_goal"]
    assert len({g.tobytes() for g in goals}) == 3
    for data, goal in zip(physics.datas, goals, strict=True):  # each arm's own world
        np.testing.assert_allclose(data.xpos[body], goal, atol=1e-6)


def test_success_is_the_tip_at_the_bottom_of_the_hole():
    task = PegInsertion()
    hole = np.zeros((3, 3))
    tips = np.array([[0.0005, 0.0, 0.0005], [0.0, 0.0, 0.005], [0.0, 0.0, HOLE_DEPTH]])
    assert task.is_success(tips, hole).tolist() == [True, False, False]
    assert task.compute_reward(tips, hole, None).tolist() == [0.0, -1.0, -1.0]
    dense = PegInsertion(reward_type="dense").compute_reward(tips, hole, None)
    np.testing.assert_allclose(dense, -np.linalg.norm(tips, axis=1), rtol=1e-6)
    # the tip from the observed pose: the peg's lower face centre
    upright = np.array([[0.5, 0.0, 0.07, 1.0, 0, 0, 0, 0, 0, 0, 0, 0, 0]])
    np.testing.assert_allclose(tip_of(upright), [[0.5, 0.0, 0.03]])


def test_a_peg_driven_onto_the_fixture_top_is_a_cartesian_reflex():
    env = gym.make("FrankaFCIPegInsertion-v0")
    obs, _ = env.reset(seed=0)
    # over the wall, not the hole: 2.05 cm off the hole's axis in x
    target = obs["desired_goal"] + np.array([0.0205, 0.0, 0.2])
    for _ in range(100):
        tip = obs["achieved_goal"]
        v = np.clip(8.0 * (target - tip) / 0.3, -0.4, 0.4)
        if np.linalg.norm(target[:2] - tip[:2]) < 0.002:
            v[2] = -0.5  # straight down at 0.15 m/s
        else:
            target[2] = 0.06
        obs, _, terminated, _, info = env.step(np.append(v, [0, 0, 0]).astype(np.float32))
        if terminated:
            break
    assert terminated
    assert "cartesian_reflex" in info["reflex_reason"] or "joint_reflex" in info["reflex_reason"]
    assert not info["is_success"]
