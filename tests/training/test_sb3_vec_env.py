"""The SB3 VecEnv adapter over the native batched env: its contract, and SAC+HER / PPO on it."""

from __future__ import annotations

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3")

from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv  # noqa: E402


def test_adapter_resets_in_the_same_step_and_hands_over_the_terminal_observation():
    env = FrankaFCISB3VecEnv(3, max_episode_steps=2)
    env.seed(4)
    obs = env.reset()
    assert obs["observation"].shape == (3, 23) and obs["desired_goal"].shape == (3, 3)
    zero = np.zeros((3, 7), dtype=np.float32)
    obs, reward, done, infos = env.step(zero)
    assert not done.any() and reward.dtype == np.float32 and len(infos) == 3
    goals = obs["desired_goal"].copy()
    obs, reward, done, infos = env.step(zero)
    assert done.all()
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True and info["cycles"] == 80
        terminal = info["terminal_observation"]
        assert terminal["desired_goal"].tobytes() == goals[i].tobytes()
        assert obs["desired_goal"][i].tobytes() != goals[i].tobytes()  # already reset
        assert env.reset_infos[i]["cycles"] == 0
    # HER reaches the vectorised reward through env_method.
    (rewards,) = env.env_method("compute_reward", goals, goals, None, indices=[0])
    assert rewards.tolist() == [0.0, 0.0, 0.0]
    assert env.get_attr("num_envs") == [3, 3, 3]


def test_sac_with_her_trains_on_the_batched_env():
    from stable_baselines3 import SAC, HerReplayBuffer

    env = FrankaFCISB3VecEnv(4, max_episode_steps=10)
    model = SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
        learning_starts=100,
        batch_size=64,
        policy_kwargs=dict(net_arch=[32, 32]),
        seed=0,
    )
    model.learn(total_timesteps=300)
    assert model.num_timesteps >= 300
    assert model.replay_buffer.size() > 0
    action, _ = model.predict(env.reset(), deterministic=True)
    assert action.shape == (4, 7) and np.all(np.abs(action) <= 1.0)


def test_ppo_trains_on_the_batched_env():
    from stable_baselines3 import PPO

    env = FrankaFCISB3VecEnv(4, max_episode_steps=10)
    model = PPO("MultiInputPolicy", env, n_steps=64, batch_size=64, n_epochs=1, seed=0)
    model.learn(total_timesteps=256)
    assert model.num_timesteps >= 256
