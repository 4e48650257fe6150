"""examples/deploy_pylibfranka.py's policy side: the numpy actor and the in-process reference."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.core import draw_episode
from franka_sim_gym.envs.tasks.reach import Reach
from tests.conftest import load_example
from tests.scripted_policies import Still, TowardTheGoal

pytest.importorskip("pylibfranka")
pytest.importorskip("stable_baselines3")

deploy = load_example("deploy_pylibfranka")

ENV_ID = "FrankaFCICartesianVelocity-v0"
KWARGS = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 20}


def _model(algo: str):
    from stable_baselines3 import PPO, SAC, TD3

    env = gym.make(ENV_ID, **KWARGS)
    kwargs = dict(policy="MultiInputPolicy", env=env, seed=0, device="cpu")
    if algo == "ppo":
        return PPO(**kwargs, n_steps=64, policy_kwargs={"net_arch": [16, 16]})
    cls = {"sac": SAC, "td3": TD3}[algo]
    return cls(**kwargs, buffer_size=1000, policy_kwargs={"net_arch": [16, 16]})


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_the_numpy_actor_acts_as_predict(algo):
    model = _model(algo)
    actor = deploy.NumpyActor.of(model)
    assert isinstance(actor, deploy.NumpyActor)
    for _ in range(20):
        obs = model.observation_space.sample()
        got, _ = actor.predict(obs)
        expected, _ = model.predict(obs, deterministic=True)
        np.testing.assert_allclose(got, expected, atol=1e-5)


def test_the_numpy_actor_keeps_the_observation_normalisation():
    """train_sb3.py's default trains behind VecNormalize: the deployed actor must see the
    observations normalised by the saved statistics, as the model did in training."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from franka_sim_gym.training.sb3_zoo import NormalizedPolicy

    model = _model("sac")
    stats = VecNormalize(DummyVecEnv([lambda: gym.make(ENV_ID, **KWARGS)]), norm_reward=False)
    for key, space in model.observation_space.spaces.items():  # statistics far from (0, 1)
        samples = np.stack([space.sample() for _ in range(50)])
        stats.obs_rms[key].update(3.0 * samples + 1.0)
    policy = NormalizedPolicy(model, stats)
    actor = deploy.NumpyActor.of(policy)
    assert isinstance(actor, NormalizedPolicy) and isinstance(actor.model, deploy.NumpyActor)
    for _ in range(20):
        obs = model.observation_space.sample()
        got, _ = actor.predict(obs)
        expected, _ = policy.predict(obs, deterministic=True)
        np.testing.assert_allclose(got, expected, atol=1e-5)
        raw, _ = model.predict(obs, deterministic=True)
        assert not np.allclose(got, raw, atol=1e-3)  # the statistics matter


def test_a_policy_without_a_deterministic_actor_is_kept():
    model = _model("ppo")
    assert deploy.NumpyActor.of(model) is model


class _Recording(TowardTheGoal):
    """TowardTheGoal that records each episode's goal."""

    def __init__(self) -> None:
        super().__init__()
        self.goals: list[np.ndarray] = []

    def predict(self, obs, deterministic=True):
        goal = obs["desired_goal"]
        if not self.goals or not np.array_equal(goal, self.goals[-1]):
            self.goals.append(goal.copy())
        return super().predict(obs, deterministic)


def test_the_in_process_reference_runs_the_deployed_reaches():
    """The same goals as deploy() draws (start noise, then goal, reach after reach), and
    a success rate that tells a reaching policy from a still one."""
    policy = _Recording()
    assert deploy.in_process(policy, ENV_ID, KWARGS, episodes=4, seed=7) == 1.0
    rng = np.random.default_rng(7)
    expected = [draw_episode(rng, 0.05, Reach())[1] for _ in range(4)]
    np.testing.assert_allclose(np.array(policy.goals), np.array(expected), atol=1e-6)
    assert deploy.in_process(Still(), ENV_ID, KWARGS, episodes=4, seed=7) == 0.0
