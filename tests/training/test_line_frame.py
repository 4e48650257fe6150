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
    """The rotation matrix of a unit quaternion w, x, y, z."""
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, np.float64))
    return m.reshape(3, 3)


def turn_about_z(turn: np.ndarray, sign: float) -> np.ndarray:
    """The 3x3 turn about z by ``sign`` times the angle of ``turn`` (cosine, sine)."""
    c, s = turn[0], sign * turn[1]
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("env_id", TASKS)
def test_in_the_line_frame_the_goal_is_straight_ahead_and_lengths_are_kept(env_id):
    obs = observations(env_id)
    as_given = {k: np.asarray(v, np.float64) for k, v in obs.items()}
    copies = {k: v.copy() for k, v in as_given.items()}
    turned, _ = to_line_frame(as_given)
    for k, v in as_given.items():  # the caller's arrays untouched (float64: no copy made)
        np.testing.assert_array_equal(v, copies[k])
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
    for k in (14, 17, 20, at, at + 7):
        np.testing.assert_allclose(
            np.linalg.norm(t[:, k : k + 3], axis=1), np.linalg.norm(o[:, k : k + 3], axis=1)
        )
    # the object's angular velocity is in its own axes (envs/tasks/objects.py): not turned
    np.testing.assert_array_equal(t[:, at + 10 :], o[:, at + 10 :])
    assert (t[:, at + 3] >= 0).all()  # the quaternion's w >= 0, as the env reports it
    assert np.ptp(o[:, 17]) > 0  # the twist moved: a turn of something, not of zeros
    # the hand from the object, turned by the line's angle: the same relative geometry
    turn = line_turn(o, obs["desired_goal"])
    for i in range(len(o)):
        back = turn_about_z(turn[i], +1.0) @ (t[i, 14:17] - t[i, at : at + 3])
        np.testing.assert_allclose(back, o[i, 14:17] - o[i, at : at + 3], atol=1e-12)
        for k in (14, 17, 20, at, at + 7):  # every base-frame vector, turned back
            back = turn_about_z(turn[i], +1.0) @ t[i, k : k + 3]
            np.testing.assert_allclose(back, o[i, k : k + 3], atol=1e-12)
        # the object's orientation turned with the frame
        turned_matrix = quaternion_matrix(t[i, at + 3 : at + 7])
        expected = turn_about_z(turn[i], -1.0) @ quaternion_matrix(o[i, at + 3 : at + 7])
        np.testing.assert_allclose(turned_matrix, expected, atol=1e-12)
        # the achieved goal turned as the desired one
        back = turn_about_z(turn[i], +1.0) @ turned["achieved_goal"][i]
        np.testing.assert_allclose(back, obs["achieved_goal"][i], atol=1e-12)


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
    # a 6-entry twist and the width (7): both velocities turned, the width not
    seven = rng.uniform(-0.5, 0.5, size=(50, 7))
    there = turn_actions(seven, turn, -1.0)
    np.testing.assert_array_equal(there[:, [2, 5, 6]], seven[:, [2, 5, 6]])
    for k in (0, 3):
        np.testing.assert_allclose(
            np.linalg.norm(there[:, k : k + 2], axis=1), np.linalg.norm(seven[:, k : k + 2], axis=1)
        )
        assert not np.allclose(there[:, k : k + 2], seven[:, k : k + 2])
    diagonal = np.array([[np.sqrt(0.5), np.sqrt(0.5)]])
    corner = turn_actions(np.ones((1, 3)), diagonal, -1.0)
    np.testing.assert_allclose(corner, [[np.sqrt(2), 0.0, 1.0]])  # outside the box


def test_a_label_outside_the_box_in_the_frame_is_refused_and_acting_is_clipped():
    obs = observations("FrankaFCIPush-v0", n=1, steps=0)
    at = obs["observation"].shape[1] - OBJECT_ENTRIES
    obs["desired_goal"][:, :2] = obs["observation"][:, at : at + 2] + 0.1  # the line at 45°
    with pytest.raises(ValueError, match="1 of 1 actions leave"):
        to_line_frame(obs, np.ones((1, 3)))  # the box's corner: sqrt(2) along the line
    _, inside = to_line_frame(obs, np.full((1, 3), 0.7))
    np.testing.assert_allclose(inside, [[0.7 * np.sqrt(2), 0.0, 0.7]])

    class Across:
        def predict(self, observation, deterministic=True):
            return np.float32([[1.0, 0.9, 0.0]]), None

    # turned back by 45°: (0.07, 1.34) in the base frame, clipped to the box
    actions, _ = LineFrame(Across()).predict(obs)
    np.testing.assert_allclose(actions, [[0.1 / np.sqrt(2), 1.0, 0.0]], atol=1e-6)


class Ahead3:
    """Push's 3-entry action: straight ahead at 0.5 in the line's frame, one row or many."""

    def predict(self, observation, deterministic=True):
        shape = observation["observation"].shape[:-1] + (3,)
        return np.broadcast_to(np.float32([0.5, 0.0, 0.0]), shape).copy(), None


def test_line_frame_acts_on_one_observation_as_on_a_batch():
    env = gym.make("FrankaFCIPush-v0")
    obs, _ = env.reset(seed=4)
    env.close()
    alone, _ = LineFrame(Ahead3()).predict(obs)
    batch, _ = LineFrame(Ahead3()).predict({k: v[None] for k, v in obs.items()})
    assert alone.shape == (3,)
    np.testing.assert_array_equal(alone, batch[0])
    at = len(obs["observation"]) - OBJECT_ENTRIES
    d = obs["desired_goal"][:2].astype(np.float64) - obs["observation"][at : at + 2]
    np.testing.assert_allclose(alone[:2], 0.5 * d / np.linalg.norm(d), atol=1e-6)


def test_the_turned_orientation_keeps_w_at_or_above_zero():
    obs = observations("FrankaFCIPush-v0", n=1, steps=0)
    at = obs["observation"].shape[1] - OBJECT_ENTRIES
    yaw, line = -1.0, 3.0  # turned by -3 rad: the composed w is cos(-2) < 0
    obs["observation"][0, at + 3 : at + 7] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    obs["desired_goal"][0, :2] = obs["observation"][0, at : at + 2] + 0.1 * np.array(
        [np.cos(line), np.sin(line)]
    )
    turned, _ = to_line_frame(obs)
    q = turned["observation"][0, at + 3 : at + 7]
    np.testing.assert_allclose(q, [-np.cos(-2.0), 0.0, 0.0, -np.sin(-2.0)], atol=1e-6)
    assert q[0] > 0


def test_an_object_on_its_goal_leaves_the_base_frame_as_it_is():
    obs = observations("FrankaFCIPush-v0", n=2, steps=0)
    at = obs["observation"].shape[1] - OBJECT_ENTRIES
    obs["desired_goal"][:, :2] = obs["observation"][:, at : at + 2]
    np.testing.assert_array_equal(line_turn(obs["observation"], obs["desired_goal"]), [[1, 0]] * 2)
    turned, _ = to_line_frame(obs)
    np.testing.assert_allclose(turned["observation"], obs["observation"], atol=1e-15)
