"""rl-zoo3 and the package (training/sb3_zoo.py): the batched env under an rl-zoo3 run, a
run's model evaluated behind the normalisation rl-zoo3 saved beside it
(examples/evaluate.py), and the shipped file."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.training import hyperparams_file

pytest.importorskip("stable_baselines3")

from stable_baselines3 import SAC  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize  # noqa: E402

from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv  # noqa: E402
from franka_sim_gym.training.sb3_zoo import (  # noqa: E402
    BatchedArms,
    NormalizedPolicy,
    entry_env_kwargs,
    with_normalization,
)
from tests.conftest import load_example  # noqa: E402

KWARGS = {"policy_hz": 10, "max_episode_steps": 4}


def zoo_run(directory, normalize: bool):
    """A model saved as rl-zoo3 saves one: <run>/<id>.zip and <run>/<id>/vecnormalize.pkl
    (statistics gathered over a few random steps, far from zero mean and unit variance)."""
    venv = DummyVecEnv([lambda: gym.make("FrankaFCI-v0", **KWARGS)])
    if normalize:
        venv = VecNormalize(venv, norm_reward=False)
    model = SAC("MultiInputPolicy", venv, policy_kwargs=dict(net_arch=[16]), seed=0)
    model.learn(8)
    path = directory / "FrankaFCI-v0.zip"
    model.save(path)
    if normalize:
        (directory / "FrankaFCI-v0").mkdir()
        venv.save(str(directory / "FrankaFCI-v0" / "vecnormalize.pkl"))
    return model, venv, path


def zoo_vec_env(n: int, env_kwargs: dict):
    """What rl-zoo3 builds for an entry before its vec_env_wrapper: SB3's make_vec_env of
    the id's single envs, each behind a Monitor (rl_zoo3 ExperimentManager.create_envs)."""
    from stable_baselines3.common.env_util import make_vec_env

    spec = gym.spec("FrankaFCI-v0")
    return make_vec_env(lambda **kwargs: spec.make(**kwargs), n_envs=n, env_kwargs=env_kwargs)


def test_batched_arms_steps_the_entrys_env_as_the_batched_env():
    """rl-zoo3's evaluation env gets no env_kwargs (the id's 25 Hz, 50 steps); wrapped,
    it is the batched env of as many arms with the wrapper's arguments (the entry's): the
    same episodes as single envs with them (arm i seeded seed + i), their length, and
    VecMonitor's statistics."""
    batched = BatchedArms(zoo_vec_env(3, {}), **KWARGS)
    assert batched.num_envs == 3 and isinstance(batched.venv.venv, FrankaFCISB3VecEnv)
    assert batched.venv.venv.vector_env.core.cycles_per_step == 100  # 10 Hz, not 25
    batched.seed(5)  # what SB3's model does with its seed
    obs = batched.reset()
    singles = [gym.make("FrankaFCI-v0", **KWARGS) for _ in range(3)]
    first = [env.reset(seed=5 + i)[0] for i, env in enumerate(singles)]
    for i in range(3):
        for key in obs:
            assert np.array_equal(obs[key][i], first[i][key])
    actions = np.tile(np.linspace(-0.5, 0.5, 7, dtype=np.float32), (3, 1))
    for _ in range(KWARGS["max_episode_steps"]):
        obs, _, dones, infos = batched.step(actions)
        expected = [env.step(actions[i]) for i, env in enumerate(singles)]
        for i in range(3):
            if not dones[i]:
                assert np.array_equal(obs["observation"][i], expected[i][0]["observation"])
    assert dones.all(), "the wrapper's episode length"
    for info, single in zip(infos, expected, strict=True):
        assert info["episode"]["l"] == KWARGS["max_episode_steps"]  # VecMonitor's
        assert info["is_success"] == single[4]["is_success"]
        assert np.array_equal(info["terminal_observation"]["observation"], single[0]["observation"])
    batched.close()


def test_batched_arms_takes_the_arguments_rl_zoo3_gave_over_its_own():
    """--env-kwargs reach the single envs rl-zoo3 builds (training and evaluation alike):
    they win over the wrapper's."""
    given = {"max_episode_steps": 3, "reward_type": "dense", "policy_hz": 25}
    batched = BatchedArms(zoo_vec_env(2, given), **KWARGS)
    core = batched.venv.venv.vector_env.core
    assert core.max_episode_steps == 3 and core.task.reward_type == "dense"
    assert core.cycles_per_step == 40  # 25 Hz given, over the wrapper's 10
    batched.close()


def test_a_normalized_run_is_evaluated_on_normalized_observations(tmp_path):
    model, venv, path = zoo_run(tmp_path, normalize=True)
    env = gym.make("FrankaFCI-v0", **KWARGS)
    policy = with_normalization(model, path, env)
    assert isinstance(policy, NormalizedPolicy)
    obs, _ = env.reset(seed=1)
    venv.training = False
    expected, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
    action, _ = policy.predict(obs, deterministic=True)
    assert np.array_equal(action, expected)
    raw, _ = model.predict(obs, deterministic=True)
    assert not np.allclose(raw, expected), "the statistics must change the action"
    # examples/evaluate.py applies it too
    loaded, _ = load_example("evaluate").load_model(path, "sac", "FrankaFCI-v0", KWARGS)
    assert isinstance(loaded, NormalizedPolicy)
    assert np.array_equal(loaded.predict(obs, deterministic=True)[0], expected)


def test_a_run_without_normalization_is_the_model_itself(tmp_path):
    model, _, path = zoo_run(tmp_path, normalize=False)
    assert with_normalization(model, path, gym.make("FrankaFCI-v0", **KWARGS)) is model


def test_the_shipped_file_is_found_and_names_its_ids():
    path = hyperparams_file("sac")
    printed = subprocess.run(
        [sys.executable, "-m", "franka_sim_gym.training", "sac"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert printed == str(path)
    with pytest.raises(ValueError, match="no shipped rl-zoo3 file for 'ppo'"):
        hyperparams_file("ppo")
    import yaml  # the test extra's (rl-zoo3 reads the file with it)

    entries = yaml.safe_load(path.read_text())
    assert {"FrankaFCI-v0", "FrankaFCICartesianVelocity-v0"} <= set(entries)
    for settings in entries.values():
        # the env's arguments are the wrapper's, which rl-zoo3's evaluation env gets too
        (wrapper,) = settings["vec_env_wrapper"]
        assert list(wrapper) == ["franka_sim_gym.training.sb3_zoo.BatchedArms"]
        assert "env_kwargs" not in settings
        assert settings["replay_buffer_class"] == "HerReplayBuffer"
        assert "copy_info_dict=True" in settings["replay_buffer_kwargs"]


def test_an_entrys_env_arguments_are_its_batched_arms_arguments():
    import yaml

    entries = yaml.safe_load(hyperparams_file("sac").read_text())
    assert entry_env_kwargs(entries["FrankaFCI-v0"]) == {"policy_hz": 5, "max_episode_steps": 10}
    cartesian = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 20}
    assert entry_env_kwargs(entries["FrankaFCICartesianVelocity-v0"]) == cartesian
    # an entry of rl-zoo3's own form: env_kwargs, a wrapper by name only
    entry = {"env_kwargs": {"policy_hz": 25}, "vec_env_wrapper": "some.Wrapper"}
    assert entry_env_kwargs(entry) == {"policy_hz": 25}
