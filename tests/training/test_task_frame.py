"""The task-frame features (training/task_frame.py): what each entry is, on the three
object tasks' real observations; the same features wherever on the table hand, object and
goal are; fixed normalisation; a model with them saves and loads; the reach refused."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.training.task_frame import (
    TaskFrame,
    frame_features,
    frame_kwargs,
    frame_rotation,
    frame_size,
)

#: (id, features) of each object task: Push 3 + 3 + 1 + 3 + 3; PickAndPlace the width
#: too; PegInsertion the 6-D twist, the quaternion and both velocities
TASKS = [
    ("FrankaFCIPush-v0", 13),
    ("FrankaFCIPickAndPlace-v0", 14),
    ("FrankaFCIPegInsertion-v0", 23),
]


def first_observation(env_id: str, seed: int = 3, moving: int = 0) -> tuple[dict, gym.Env]:
    """The observation after the reset, or after ``moving`` steps of a slow drift
    (the twist and, where the hand holds it, the object's velocity then not zero)."""
    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    action = np.zeros(env.action_space.shape, np.float32)
    action[:3] = [0.2, -0.1, 0.1]
    if env.action_space.shape == (4,):  # PickAndPlace's hand: open
        action[3] = 1.0
    for _ in range(moving):
        obs, *_ = env.step(action)
    return {k: th.as_tensor(v[None], dtype=th.float64) for k, v in obs.items()}, env


@pytest.mark.parametrize("env_id, size", TASKS)
def test_the_features_are_the_object_from_the_tcp_and_the_goal_from_the_object(env_id, size):
    obs, env = first_observation(env_id, moving=3)
    rotation = frame_rotation(env.observation_space, gym.spec(env_id).kwargs)
    assert rotation == (env_id == "FrankaFCIPegInsertion-v0")
    assert frame_size(env.observation_space["observation"].shape[0], rotation) == size
    o, goal = obs["observation"][0].numpy(), obs["desired_goal"][0].numpy()
    features = frame_features(obs["observation"], obs["desired_goal"], rotation)[0].numpy()
    assert features.shape == (size,)
    at = len(o) - 13
    tcp, obj = o[14:17], o[at : at + 3]
    if env_id != "FrankaFCIPegInsertion-v0":  # the object is the achieved goal
        np.testing.assert_array_equal(obj, obs["achieved_goal"][0].numpy())
    np.testing.assert_array_equal(features[0:3], obj - tcp)
    np.testing.assert_array_equal(features[3:6], goal - obj)
    assert features[6] == tcp[2]  # the TCP's height above the table
    twist = 6 if rotation else 3
    assert np.abs(o[17:20]).max() > 0.01  # the hand is moving: the twist is not zeros
    np.testing.assert_array_equal(features[7 : 7 + twist], o[17 : 17 + twist])
    if env_id == "FrankaFCIPickAndPlace-v0":
        assert features[10] == o[23] > 0.07  # the hand's width, open
    if rotation:  # the held peg moves with the hand: quaternion, then both velocities
        assert np.abs(o[at + 7 : at + 10]).max() > 0.01
        np.testing.assert_array_equal(features[13:], o[at + 3 :])
    else:
        np.testing.assert_array_equal(features[-3:], o[at + 7 : at + 10])  # linear velocity
    # with the elbow: the same, then joint 4's angle
    assert frame_size(len(o), rotation, elbow=True) == size + 1
    elbow = frame_features(obs["observation"], obs["desired_goal"], rotation, elbow=True)
    np.testing.assert_array_equal(elbow[0, :size].numpy(), features)
    assert elbow[0, size] == o[3] < -1.5  # (folded: the FR3's q4 is in [-3.07, -0.07])
    env.close()


def test_the_features_do_not_move_with_the_scene():
    obs, env = first_observation("FrankaFCIPush-v0")
    moved = {k: v.clone() for k, v in obs.items()}
    shift = th.tensor([0.07, -0.05], dtype=th.float64)
    at = moved["observation"].shape[1] - 13
    for columns in (slice(14, 16), slice(at, at + 2)):  # the TCP's and the block's x, y
        moved["observation"][:, columns] += shift
    moved["desired_goal"][:, :2] += shift
    before = frame_features(obs["observation"], obs["desired_goal"], False)
    after = frame_features(moved["observation"], moved["desired_goal"], False)
    th.testing.assert_close(after, before, rtol=0, atol=1e-12)
    env.close()


def test_the_extractor_normalises_with_the_given_statistics():
    obs, env = first_observation("FrankaFCIPush-v0")
    space = env.observation_space
    mean, std = list(np.arange(13.0)), list(np.full(13, 2.0))
    extractor = TaskFrame(space, rotation=False, mean=mean, std=std)
    assert extractor.features_dim == 13
    floats = {k: v.float() for k, v in obs.items()}
    raw = frame_features(floats["observation"], floats["desired_goal"], False)
    th.testing.assert_close(extractor(floats), (raw - th.arange(13.0)) / 2.0)
    th.testing.assert_close(TaskFrame(space)(floats), raw)  # no statistics: as they are
    with pytest.raises(ValueError, match="mean has 12 entries, expected 13"):
        TaskFrame(space, mean=mean[:12], std=std)
    with pytest.raises(ValueError, match="std must be > 0"):
        TaskFrame(space, mean=mean, std=[0.0] * 13)
    env.close()


@pytest.mark.parametrize("env_id", ["FrankaFCI-v0", "FrankaFCIPushJointPosition-v0"])
def test_the_reach_and_the_joint_interfaces_are_refused_by_name(env_id):
    # the reach has no object; a joint-interface policy needs the joint state
    env = gym.make(env_id)
    assert frame_rotation(env.observation_space, gym.spec(env_id).kwargs) is None
    with pytest.raises(ValueError, match="needs a task with an object and a Cartesian"):
        frame_kwargs(None, gym.spec(env_id).kwargs, env.observation_space)
    if env_id == "FrankaFCI-v0":
        with pytest.raises(ValueError, match="TaskFrame needs a task with an object"):
            TaskFrame(env.observation_space)
    env.close()


def test_a_sac_model_on_the_task_frame_saves_and_loads_with_its_statistics(tmp_path):
    from stable_baselines3 import SAC

    th.set_num_threads(1)
    env = gym.make("FrankaFCIPush-v0", max_episode_steps=5)
    kwargs = dict(rotation=False, mean=[0.1] * 13, std=[0.5] * 13)
    model = SAC(
        "MultiInputPolicy",
        env,
        buffer_size=10,
        seed=0,
        policy_kwargs=dict(
            net_arch=[16], features_extractor_class=TaskFrame, features_extractor_kwargs=kwargs
        ),
    )
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "model.zip")
    loaded = SAC.load(tmp_path / "model.zip", env=env)
    assert isinstance(loaded.actor.features_extractor, TaskFrame)
    th.testing.assert_close(loaded.actor.features_extractor.std, th.full((13,), 0.5))
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], action)
    env.close()
