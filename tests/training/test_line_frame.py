"""The line's frame (training/line_frame.py) on the object tasks' real observations: the
goal straight ahead of the object, lengths and heights kept, the object's orientation
turned with the rest, a policy's action turned back."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.tasks.objects import OBJECT_ENTRIES
from franka_sim_gym.training.line_frame import (
    LineFrame,
    line_turn,
    to_line_frame,
    turn_actions,
)

TASKS = ["FrankaFCIPush-v0", "FrankaFCIPickAndPlace-v0", "FrankaFCIPegInsertion-v0"]


def observations(env_id: str, n: int = 6, steps: int = 5) -> dict:
    """A batch of real observations: n arms after ``steps`` random actions (moving hand,
    twist not zero; the object at rest or pushed)."""
    envs = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    obs, _ = envs.reset(seed=11)
    envs.action_space.seed(5)
    for _ in range(steps):
        obs, *_ = envs.step(0.3 * envs.action_space.sample())
    envs.close()
    return obs


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, np.float64))
    return m.reshape(3, 3)


def turn_about_z(turn: np.ndarray, sign: float) -> np.ndarray:
    c, s = turn[0], sign * turn[1]
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("env_id", TASKS)
def test_in_the_line_frame_the_goal_is_straight_ahead_and_lengths_are_kept(env_id):
    obs = observations(env_id)
    turned, _ = to_line_frame(obs)
    o, t = np.asarray(obs["observation"], np.float64), turned["observation"]
    at = o.shape[1] - OBJECT_ENTRIES
    ahead = turned["desired_goal"] - t[:, at : at + 3]
    base = obs["desired_goal"] - o[:, at : at + 3]
    np.testing.assert_allclose(ahead[:, 1], 0.0, atol=1e-12)  # no way across
    np.testing.assert_allclose(ahead[:, 0], np.hypot(base[:, 0], base[:, 1]), rtol=1e-12)
    assert (ahead[:, 0] > 0).all()
    np.testing.assert_array_equal(ahead[:, 2], base[:, 2])  # heights unchanged
    # the joint state as it was; every vector's length kept (a turn, not a scaling)
    np.testing.assert_array_equal(t[:, :14], o[:, :14])
    for k in (14, 17, 20, at, at + 7, at + 10):
        np.testing.assert_allclose(
            np.linalg.norm(t[:, k : k + 3], axis=1), np.linalg.norm(o[:, k : k + 3], axis=1)
        )
    assert np.ptp(o[:, 17]) > 0  # the twist moved: a turn of something, not of zeros
    # the hand from the object, turned by the line's angle: the same relative geometry
    turn = line_turn(o, obs["desired_goal"])
    for i in range(len(o)):
        back = turn_about_z(turn[i], +1.0) @ (t[i, 14:17] - t[i, at : at + 3])
        np.testing.assert_allclose(back, o[i, 14:17] - o[i, at : at + 3], atol=1e-12)
        for k in (14, 17, 20, at, at + 7, at + 10):  # every vector, turned back
            back = turn_about_z(turn[i], +1.0) @ t[i, k : k + 3]
            np.testing.assert_allclose(back, o[i, k : k + 3], atol=1e-12)
        # the object's orientation turned with the frame
        turned_matrix = quaternion_matrix(t[i, at + 3 : at + 7])
        expected = turn_about_z(turn[i], -1.0) @ quaternion_matrix(o[i, at + 3 : at + 7])
        np.testing.assert_allclose(turned_matrix, expected, atol=1e-12)


class Ahead:
    """In the line's frame: straight ahead at 0.5, 0.2 up, turning about the line's x."""

    def predict(self, observation, deterministic=True):
        n = len(observation["observation"])
        assert observation["observation"].dtype == np.float32  # the env's dtype kept
        action = np.tile(np.float32([0.5, 0.0, 0.2, 0.3, 0.0, 0.0]), (n, 1))
        return action, None


def test_a_policy_in_the_line_frame_acts_along_the_line_in_the_base_frame():
    obs = observations("FrankaFCIPegInsertion-v0")  # a 6-entry twist: both turned
    actions, _ = LineFrame(Ahead()).predict(obs)
    assert actions.dtype == np.float32
    o = obs["observation"]
    at = o.shape[1] - OBJECT_ENTRIES
    d = obs["desired_goal"][:, :2].astype(np.float64) - o[:, at : at + 2]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_allclose(actions[:, :2], 0.5 * d, atol=1e-6)
    np.testing.assert_allclose(actions[:, 2], 0.2)
    np.testing.assert_allclose(actions[:, 3:5], 0.3 * d, atol=1e-6)
    np.testing.assert_allclose(actions[:, 5], 0.0)


def test_actions_turn_there_and_back_and_stay_in_the_box():
    rng = np.random.default_rng(0)
    turn = rng.normal(size=(50, 2))
    turn /= np.linalg.norm(turn, axis=1, keepdims=True)
    actions = rng.uniform(-0.7, 0.7, size=(50, 4))  # PickAndPlace: the width last
    actions[:, :2] *= 0.7 / np.maximum(np.linalg.norm(actions[:, :2], axis=1), 0.7)[:, None]
    there = turn_actions(actions, turn, -1.0)
    np.testing.assert_array_equal(there[:, 2:], actions[:, 2:])  # height, width: not turned
    np.testing.assert_allclose(turn_actions(there, turn, +1.0), actions, atol=1e-12)
    corner = turn_actions(np.ones((1, 3)), np.array([[np.sqrt(0.5), np.sqrt(0.5)]]), -1.0)
    np.testing.assert_allclose(corner, [[1.0, 0.0, 1.0]])  # sqrt(2) ahead, clipped to 1


def test_an_object_on_its_goal_leaves_the_base_frame_as_it_is():
    obs = observations("FrankaFCIPush-v0", n=2, steps=0)
    at = obs["observation"].shape[1] - OBJECT_ENTRIES
    obs["desired_goal"][:, :2] = obs["observation"][:, at : at + 2]
    np.testing.assert_array_equal(line_turn(obs["observation"], obs["desired_goal"]), [[1, 0]] * 2)
    turned, _ = to_line_frame(obs)
    np.testing.assert_allclose(turned["observation"], obs["observation"], atol=1e-15)
