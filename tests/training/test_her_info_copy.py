"""The infos SB3's HerReplayBuffer(copy_info_dict=True) deep-copies at every gradient step
(the shipped rl-zoo3 file's buffer): the env's InfoRow copies as a dict does, faster."""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.infos import InfoRow

pytest.importorskip("stable_baselines3")

from stable_baselines3 import HerReplayBuffer  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402


def reflex_info() -> dict:
    """The info of a step that ended in a reflex (unfiltered joint jumps), error names set."""
    env = gym.make("FrankaFCI-v0", action_filter="none", max_episode_steps=6)
    env.reset(seed=0)
    for _ in range(6):
        _, _, terminated, _, info = env.step(np.ones(7, dtype=np.float32))
        if terminated:
            return info
    raise AssertionError("a full unfiltered joint jump must trip a reflex")


def test_a_deep_copy_is_the_dicts_and_shares_nothing_mutable():
    info = reflex_info()
    assert type(info) is InfoRow and info["reflex_reason"] and info["errors"]
    info["terminal_observation"] = {"observation": np.zeros(3)}  # as SB3's VecEnvs add
    copied = copy.deepcopy(info)
    expected = copy.deepcopy(dict(info))
    assert type(copied) is InfoRow and copied.keys() == expected.keys()
    for key, value in expected.items():
        if isinstance(value, np.ndarray):
            assert copied[key] is not info[key] and np.array_equal(copied[key], value), key
        elif isinstance(value, dict):
            assert copied[key] is not info[key], key
            assert np.array_equal(copied[key]["observation"], value["observation"])
        else:
            assert copied[key] == value and type(copied[key]) is type(value), key
    copied["O_F_ext_hat_K"][:] = 99.0
    copied["terminal_observation"]["observation"][:] = 99.0
    copied["errors"] = ()
    assert not np.any(info["O_F_ext_hat_K"] == 99.0)
    assert not np.any(info["terminal_observation"]["observation"] == 99.0)
    assert info["errors"]


def test_shared_and_circular_entries_copy_as_a_dicts_do():
    array = np.arange(3.0)
    info = InfoRow(a=array, b=array)
    info["own"] = [info]  # a wrapper could keep a reference back
    copied = copy.deepcopy(info)
    assert copied["a"] is copied["b"] and copied["a"] is not array
    assert copied["own"][0] is copied


def test_her_relabels_the_same_rewards_from_env_infos_and_plain_dicts():
    kwargs = {"action_filter": "none", "max_episode_steps": 6}
    env = make_vec_env("FrankaFCI-v0", n_envs=4, seed=0, env_kwargs=kwargs)
    buffer = HerReplayBuffer(
        200, env.observation_space, env.action_space, env=env, n_envs=4, copy_info_dict=True
    )
    rng = np.random.default_rng(0)
    obs = env.reset()
    charged = 0
    for _ in range(30):
        action = rng.uniform(-1, 1, (4, 7)).astype(np.float32)
        next_obs, reward, done, infos = env.step(action)
        charged += int((reward < -1.0).sum())
        buffer.add(obs, next_obs, action, reward, done, infos)
        obs = next_obs
    assert charged > 0, "random unfiltered actions must trip charged reflexes"
    rows = buffer.infos.copy()
    plain = np.empty_like(rows)
    for index in np.ndindex(rows.shape):
        plain[index] = None if rows[index] is None else dict(rows[index])
    drawn = []
    for infos in (rows, plain):
        buffer.infos = infos
        np.random.seed(1)  # HER draws with numpy's global generator
        drawn.append(np.concatenate([buffer.sample(64).rewards.numpy() for _ in range(8)]))
    assert np.array_equal(drawn[0], drawn[1])
    assert (drawn[0] < -1.0).any(), "relabelled reflex steps keep their charge"
