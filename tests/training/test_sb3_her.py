"""The HER replay buffer that keeps the reflex charge (training/sb3_her.py), inside SB3's SAC."""

from __future__ import annotations

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3")

from stable_baselines3 import SAC, HerReplayBuffer  # noqa: E402

from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer  # noqa: E402
from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv  # noqa: E402

HER = dict(n_sampled_goal=4, goal_selection_strategy="future")


def collect(buffer_class, steps: int = 48) -> SAC:
    """SAC's own collection (uniform random actions before learning starts) on arms whose
    unfiltered joint-position actions trip reflexes: the model, its buffer holding the
    transitions HER stores."""
    env = FrankaFCISB3VecEnv(4, action_filter="none", max_episode_steps=6)
    model = SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=buffer_class,
        replay_buffer_kwargs=HER,
        buffer_size=1000,
        learning_starts=10_000,  # collection only
        policy_kwargs=dict(net_arch=[16]),
        seed=3,
    )
    model.learn(total_timesteps=steps)
    return model


def reflex_steps(buffer) -> tuple[np.ndarray, np.ndarray]:
    """(row, arm) of the stored steps that ended in a reflex: done, not a time limit, and
    charged in the reward the env gave (sparse rewards are 0 or -1 otherwise)."""
    n = buffer.pos
    ended = (buffer.dones[:n] > 0) & (buffer.timeouts[:n] == 0)
    charged = buffer.rewards[:n] < -1.0
    assert np.array_equal(ended, charged), "every reflex step, and only those, is charged"
    rows, arms = np.nonzero(ended)
    assert len(rows) > 0, "random unfiltered actions must trip reflexes"
    return rows, arms


def sampled_reflex_steps(buffer, batches: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """HER's own samples (its public ``sample``) of steps that ended in a reflex (done,
    not a time limit): (whether each was relabelled, its reward). "future" relabels an
    episode's last step with the goal it reached itself, so a relabelled reflex step's
    desired goal is its next achieved goal: distance 0, only a charge can be left."""
    np.random.seed(2)  # HER draws with numpy's global generator
    relabelled, rewards = [], []
    for _ in range(batches):
        batch = buffer.sample(512)
        ended = batch.dones.numpy().ravel() == 1.0
        goal = batch.observations["desired_goal"].numpy()[ended]
        reached = batch.next_observations["achieved_goal"].numpy()[ended]
        relabelled.append(np.all(goal == reached, axis=1))
        rewards.append(batch.rewards.numpy().ravel()[ended])
    relabelled, rewards = np.concatenate(relabelled), np.concatenate(rewards)
    assert relabelled.sum() > 0 and (~relabelled).sum() > 0, "both kinds must be drawn"
    return relabelled, rewards


def test_relabelled_reflex_steps_keep_their_charge():
    buffer = collect(ReflexChargedHerReplayBuffer).replay_buffer
    rows, arms = reflex_steps(buffer)
    charges = buffer.infos.penalty[rows, arms]
    assert np.array_equal(charges, buffer.rewards[rows, arms] + 1.0)  # what the env charged
    relabelled, rewards = sampled_reflex_steps(buffer)
    assert np.all(rewards[relabelled] < -1.0)
    assert set(rewards[relabelled].tolist()) <= set(charges.astype(np.float32).tolist())
    # a step HER kept as it was has the env's reward, charge included
    assert set(rewards[~relabelled].tolist()) <= set(buffer.rewards[rows, arms].tolist())
    # the charge is one float a transition; steps that did not end in a reflex carry 0
    quiet = buffer.infos.penalty[: buffer.pos][buffer.rewards[: buffer.pos] >= -1.0]
    assert quiet.size > 0 and np.all(quiet == 0.0)


def test_sb3s_own_buffer_would_relabel_a_reflex_as_a_success():
    """Why the buffer exists: without the infos, HER's relabelled reflex step is a
    terminal transition of reward 0, the best a transition can get."""
    buffer = collect(HerReplayBuffer).replay_buffer
    reflex_steps(buffer)
    relabelled, rewards = sampled_reflex_steps(buffer)
    assert np.all(rewards[relabelled] == 0.0)
    assert np.all(rewards[~relabelled] < -1.0)


def test_the_charges_survive_saving_the_replay_buffer(tmp_path):
    model = collect(ReflexChargedHerReplayBuffer, steps=24)
    buffer = model.replay_buffer
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    model.load_replay_buffer(tmp_path / "buffer.pkl")
    loaded = model.replay_buffer
    assert loaded is not buffer
    assert np.array_equal(loaded.infos.penalty, buffer.infos.penalty)
    rows, arms = reflex_steps(loaded)
    relabelled, rewards = sampled_reflex_steps(loaded)
    charges = buffer.infos.penalty[rows, arms].astype(np.float32)
    assert np.all(rewards[relabelled] < -1.0)
    assert set(rewards[relabelled].tolist()) <= set(charges.tolist())


def test_copy_info_dict_is_refused_with_the_reason():
    env = FrankaFCISB3VecEnv(2, max_episode_steps=4)
    with pytest.raises(ValueError, match="keeps the reflex charge itself: copy_info_dict"):
        ReflexChargedHerReplayBuffer(
            100, env.observation_space, env.action_space, env=env, copy_info_dict=True
        )


def test_a_buffer_sized_to_the_run_samples_what_the_default_size_samples():
    """examples/train_sb3.py sizes the buffer to the run (HER scans every slot at each
    sample): with nothing overwritten, the same seed draws the same transitions and goals
    as SB3's million-slot default."""
    env = FrankaFCISB3VecEnv(4, action_filter="none", max_episode_steps=6)
    small, large = (
        ReflexChargedHerReplayBuffer(
            size, env.observation_space, env.action_space, env=env, n_envs=4, **HER
        )
        for size in (4 * 40, 1_000_000)
    )
    env.seed(5)
    obs = env.reset()
    rng = np.random.default_rng(5)
    for _ in range(30):
        action = rng.uniform(-1, 1, (4, 7)).astype(np.float32)
        next_obs, reward, done, infos = env.step(action)
        for buffer in (small, large):
            buffer.add(obs, next_obs, action, reward, done, infos)
        obs = next_obs
    draws = []
    for buffer in (small, large):
        np.random.seed(11)
        draws.append([buffer.sample(64) for _ in range(3)])
    for a, b in zip(*draws, strict=True):
        for key in a.observations:
            assert np.array_equal(a.observations[key].numpy(), b.observations[key].numpy())
        assert np.array_equal(a.rewards.numpy(), b.rewards.numpy())
        assert np.array_equal(a.actions.numpy(), b.actions.numpy())
