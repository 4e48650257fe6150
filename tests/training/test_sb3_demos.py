"""Learning from demonstrations (training/sb3_demos.py): the batches' demonstration share,
the reflex charge of relabelled demonstrations, the behaviour-cloning term, and
examples/train_sb3.py --demos end to end."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

minari = pytest.importorskip("minari")
sb3 = pytest.importorskip("stable_baselines3")

import torch as th  # noqa: E402

from franka_sim_gym.training.datasets import names, record  # noqa: E402
from franka_sim_gym.training.sb3_demos import (  # noqa: E402
    BehaviourCloningAdam,
    DemoMixedHerReplayBuffer,
    add_behaviour_cloning,
    behaviour_cloning,
    demo_arrays,
)
from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer  # noqa: E402
from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv  # noqa: E402
from tests.conftest import load_example  # noqa: E402
from tests.training.test_datasets import REFLEXES, RandomPolicy  # noqa: E402
from tests.training.test_sb3_her import sampled_reflex_steps  # noqa: E402

HER = dict(n_sampled_goal=4, goal_selection_strategy="future")
ENV_KWARGS = {**gym.spec("FrankaFCI-v0").kwargs, **REFLEXES}


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """One torch thread, as training runs (two wait for each other on a busy host)."""
    threads = th.get_num_threads()
    th.set_num_threads(1)
    yield
    th.set_num_threads(threads)


class HalfStill(RandomPolicy):
    """Random unfiltered joint targets (a reflex within a few steps) on odd arms; the
    even arms hold still until the time limit."""

    def __call__(self, obs: dict) -> np.ndarray:
        actions = super().__call__(obs)
        actions[::2] = 0.0
        return actions


@pytest.fixture(scope="module")
def demos(datasets_dir):
    """Reach episodes: half end in a reflex, half at the time limit."""
    return record(
        "tests/demos-v0",
        "FrankaFCI-v0",
        HalfStill(7, seed=1),
        12,
        env_kwargs=REFLEXES,
        num_envs=12,
    )


def rows(observations: np.ndarray) -> set[bytes]:
    return {row.tobytes() for row in observations}


def online_episode(buffer, env, seed: int = 100) -> set[bytes]:
    """Steps of random actions until every arm has finished an episode, added to the
    buffer as SB3 adds them; the observations stored."""
    env.seed(seed)
    obs = env.reset()
    rng = np.random.default_rng(seed)
    seen, finished = set(), np.zeros(env.num_envs, dtype=bool)
    while not finished.all():
        action = rng.uniform(-1, 1, (env.num_envs, 7)).astype(np.float32)
        next_obs, reward, done, infos = env.step(action)
        buffer.add(obs, next_obs, action, reward, done, infos)
        seen |= rows(obs["observation"])
        finished |= done
        obs = next_obs
    return seen


def test_batches_are_demonstrations_then_the_set_share(demos):
    env = FrankaFCISB3VecEnv(2, **ENV_KWARGS)
    buffer = DemoMixedHerReplayBuffer(
        200,
        env.observation_space,
        env.action_space,
        env=env,
        n_envs=2,
        demos="tests/demos-v0",
        demo_fraction=0.25,
        **HER,
    )
    recorded = rows(demo_arrays(demos)[0]["observation"])
    assert buffer.demos.pos == demos.total_steps  # every recorded transition, once
    # No online episode has finished: the whole batch is demonstrations.
    batch = buffer.sample(40).observations["observation"].numpy()
    assert rows(batch) <= recorded
    online = online_episode(buffer, env)
    assert not online & recorded
    np.random.seed(4)
    for _ in range(3):
        batch = buffer.sample(40).observations["observation"].numpy()
        assert rows(batch[:10]) <= recorded  # round(0.25 * 40) demonstrations first
        assert rows(batch[10:]) <= online
    env.close()


def test_relabelled_demonstrations_keep_their_reflex_charge(demos):
    env = FrankaFCISB3VecEnv(1, **ENV_KWARGS)
    buffer = DemoMixedHerReplayBuffer(
        10, env.observation_space, env.action_space, env=env, demos=demos, **HER
    )
    charges = [
        float(e.infos["reflex_penalty"][-1]) for e in demos.iterate_episodes() if e.terminations[-1]
    ]
    assert charges and all(c < 0 for c in charges), "random unfiltered actions trip reflexes"
    stored = buffer.demos.infos.penalty[: buffer.demos.pos, 0]
    assert sorted(stored[stored != 0].tolist()) == sorted(charges)
    # an episode cut by the time limit is no terminal transition (SB3's timeouts)
    ends = buffer.demos.dones[: buffer.demos.pos, 0] > 0
    timeouts = buffer.demos.timeouts[: buffer.demos.pos, 0] > 0
    assert ends.sum() == demos.total_episodes
    assert timeouts.sum() == demos.total_episodes - len(charges) > 0
    assert np.array_equal(ends & ~timeouts, stored != 0)
    relabelled, rewards = sampled_reflex_steps(buffer)  # all demonstrations (no online yet)
    assert np.all(rewards[relabelled] < -1.0)
    assert set(rewards[relabelled].tolist()) <= set(np.float32(charges).tolist())
    assert all(names(e.infos["reflex_reason"][-1]) for e in demos if e.terminations[-1])
    env.close()


def test_a_dataset_of_another_env_is_refused(demos):
    env = FrankaFCISB3VecEnv(1, action_interface="cartesian_velocity", max_episode_steps=6)
    match = r"recorded on FrankaFCI-v0 with arguments .*actions \(7,\); the env .*actions \(6,\)"
    with pytest.raises(ValueError, match=match):
        DemoMixedHerReplayBuffer(
            10, env.observation_space, env.action_space, env=env, demos=demos, **HER
        )
    env.close()


class Smooth:
    """Joint targets that depend on the observed joint positions only."""

    def __call__(self, obs: dict) -> np.ndarray:
        return 0.5 * np.sin(3.0 * obs["observation"][:, :7])


def test_behaviour_cloning_fits_the_actor_to_the_recorded_actions(demos):
    # a demonstrator whose action is a function of the observation (learnable)
    clean = record("tests/smooth-v0", "FrankaFCI-v0", Smooth(), 4, env_kwargs=REFLEXES, num_envs=4)
    env = gym.make("FrankaFCI-v0", **REFLEXES)
    model = sb3.SAC(
        "MultiInputPolicy", env, buffer_size=10, seed=0, policy_kwargs=dict(net_arch=[32, 32])
    )
    obs, actions = demo_arrays(clean)

    def error(model) -> float:
        with th.no_grad():
            batch, _ = model.policy.obs_to_tensor(obs)
            return float(
                ((model.actor(batch, deterministic=True) - th.tensor(actions)) ** 2).mean()
            )

    before = error(model)
    losses = behaviour_cloning(model.policy, clean, 200, batch_size=64)
    assert len(losses) == 200 and error(model) < 0.5 * before
    # ``prepare`` gives the pairs it is fitted on (here: the actions halved)
    halved = sb3.SAC(
        "MultiInputPolicy", env, buffer_size=10, seed=0, policy_kwargs=dict(net_arch=[32, 32])
    )
    behaviour_cloning(halved.policy, clean, 200, batch_size=64, prepare=lambda o, a: (o, a / 2))
    with th.no_grad():
        batch, _ = halved.policy.obs_to_tensor(obs)
        fitted = halved.actor(batch, deterministic=True).numpy()
    assert ((fitted - actions / 2) ** 2).mean() < 0.5 * ((fitted - actions) ** 2).mean()
    # The term SAC's actor steps carry: with no other gradient, its steps clone.
    for weight, moves in ((0.0, False), (1.0, True)):
        fresh = sb3.SAC(
            "MultiInputPolicy", env, buffer_size=10, seed=1, policy_kwargs=dict(net_arch=[32, 32])
        )
        optimizer = BehaviourCloningAdam(
            fresh.actor.parameters(), fresh.actor, obs, actions, weight, batch_size=64, lr=1e-3
        )
        start = error(fresh)
        for _ in range(100):
            optimizer.zero_grad()
            optimizer.step()
        assert (error(fresh) < 0.5 * start) == moves
    env.close()


def test_a_noise_injected_dataset_is_cloned_from_the_demonstrators_actions(datasets_dir):
    noisy = record(
        "tests/noisy-bc-v0", "FrankaFCI-v0", Smooth(), 2, env_kwargs=REFLEXES, num_envs=2, noise=0.2
    )
    obs, actions = demo_arrays(noisy)
    # the labels: what the demonstrator chose at each recorded state, not what ran there
    np.testing.assert_array_equal(actions, Smooth()(obs).astype(np.float32))
    executed = np.concatenate([episode.actions for episode in noisy.iterate_episodes()])
    assert executed.shape == actions.shape and np.abs(executed - actions).mean() > 0.05


def test_cloning_sets_the_exploration_and_the_warmup_holds_sacs_gradient_back(demos):
    env = gym.make("FrankaFCI-v0", **REFLEXES)
    model = sb3.SAC(
        "MultiInputPolicy", env, buffer_size=10, seed=0, policy_kwargs=dict(net_arch=[32, 32])
    )
    obs, actions = demo_arrays(demos)
    batch, _ = model.policy.obs_to_tensor(obs)
    with th.no_grad():
        _, log_std, _ = model.actor.get_action_dist_params(batch)
    assert abs(float(log_std.mean())) < 0.5  # an untrained actor: std about 1
    behaviour_cloning(model.policy, demos, 300, batch_size=64, exploration_std=0.1)
    with th.no_grad():
        _, log_std, _ = model.actor.get_action_dist_params(batch)
    assert float(log_std.mean()) == pytest.approx(np.log(0.1), abs=0.3)
    # warmup: for 3 steps SAC's own gradient is dropped (the actor stands still without
    # a cloning term), then it moves the actor
    optimizer = BehaviourCloningAdam(
        model.actor.parameters(), model.actor, obs, actions, 0.0, warmup=3, lr=1e-3
    )
    moved = []
    for _ in range(5):
        before = [p.detach().clone() for p in model.actor.parameters()]
        optimizer.zero_grad()
        model.actor(batch, deterministic=True).sum().backward()  # a stand-in actor loss
        optimizer.step()
        after = model.actor.parameters()
        moved.append(any(not th.equal(b, p) for b, p in zip(before, after, strict=True)))
    assert moved == [False, False, False, True, True]

    # with a cloning term, a warm-up step is exactly the cloning step alone
    def one_step(sac_loss: bool) -> list[th.Tensor]:
        fresh = sb3.SAC(
            "MultiInputPolicy", env, buffer_size=10, seed=2, policy_kwargs=dict(net_arch=[32])
        )
        step = BehaviourCloningAdam(
            fresh.actor.parameters(), fresh.actor, obs, actions, 1.0, 64, warmup=2, lr=1e-2
        )
        step.zero_grad()
        if sac_loss:
            (100.0 * fresh.actor(batch, deterministic=True).sum()).backward()
        step.step()
        return [p.detach().clone() for p in fresh.actor.parameters()]

    for a, b in zip(one_step(True), one_step(False), strict=True):
        assert th.equal(a, b)
    env.close()


def test_sacs_actor_steps_carry_the_behaviour_cloning_term(demos):
    env = FrankaFCISB3VecEnv(2, **ENV_KWARGS)
    model = sb3.SAC(
        "MultiInputPolicy",
        env,
        learning_starts=2,
        batch_size=32,
        seed=0,
        buffer_size=100,
        replay_buffer_class=DemoMixedHerReplayBuffer,
        replay_buffer_kwargs=dict(demos=demos, **HER),
        policy_kwargs=dict(net_arch=[16]),
    )
    lr = model.actor.optimizer.param_groups[0]["lr"]
    optimizer = add_behaviour_cloning(model, demos, weight=2.0)
    assert model.actor.optimizer is optimizer and optimizer.param_groups[0]["lr"] == lr
    assert np.isnan(optimizer.last_loss)
    model.learn(8)  # SAC's own train(): its actor steps are this optimizer's
    assert np.isfinite(optimizer.last_loss) and optimizer.last_loss > 0
    env.close()


def test_train_sb3_learns_from_a_dataset_and_saves_a_model_that_loads_without_it(
    datasets_dir, tmp_path, monkeypatch, capsys
):
    train_sb3 = load_example("train_sb3")
    env_kwargs = {**train_sb3.DEFAULT_ENV_KWARGS, **REFLEXES}
    recorded = record(
        "tests/train-v0", "FrankaFCI-v0", RandomPolicy(7, seed=2), 4, env_kwargs=env_kwargs
    ).total_steps
    out = tmp_path / "run"
    argv = ["train_sb3.py", "--env-id", "FrankaFCI-v0", "--env-kwargs", json.dumps(REFLEXES)]
    argv += ["--demos", "tests/train-v0", "--bc-weight", "1", "--bc-steps", "5", "--normalize"]
    argv += ["--num-envs", "2", "--steps", "24", "--evals", "1", "--eval-episodes", "2"]
    argv += ["--net", "16", "--learning-starts", "2", "--gamma", "0.9", "--no-progress"]
    monkeypatch.setattr("sys.argv", [*argv, "--out", str(out)])
    train_sb3.main()
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("eval: success_rate=")
    progress = (out / "progress.csv").read_text().splitlines()
    assert len(progress) > 1 and "train/actor_loss" in progress[0]  # it learnt
    minari.delete_dataset("tests/train-v0")
    env = gym.make("FrankaFCI-v0", **env_kwargs)
    model = sb3.SAC.load(out / "model.zip", env=env)
    assert model.replay_buffer_class is ReflexChargedHerReplayBuffer
    assert model.gamma == 0.9
    # the normalisation's statistics started from every recorded observation
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    stats = VecNormalize.load(str(out / "model" / "vecnormalize.pkl"), DummyVecEnv([lambda: env]))
    assert stats.obs_rms["observation"].count > recorded + 24
    env.close()


def test_train_bc_and_train_sb3_on_the_task_frame_of_noise_injected_push_demonstrations(
    datasets_dir, tmp_path, monkeypatch, capsys
):
    from franka_sim_gym.training.task_frame import TaskFrame, frame_statistics

    scripted = load_example("scripted")
    push = {"max_episode_steps": 8}
    policy = scripted.ScriptedPolicy("FrankaFCIPush-v0", env_kwargs=push)
    noisy = record("tests/push-dart-v0", "FrankaFCIPush-v0", policy, 2, 0, push, noise=0.1)
    mean, std = frame_statistics(noisy, rotation=False)
    # behaviour cloning (--features auto: the task frame for an object task)
    out = tmp_path / "bc"
    argv = ["train_bc.py", "--demos", "tests/push-dart-v0", "--steps", "20", "--net", "16"]
    monkeypatch.setattr("sys.argv", [*argv, "--eval-episodes", "2", "--out", str(out)])
    load_example("train_bc").main()
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("bc: success_rate=")
    assert not (out / "model" / "vecnormalize.pkl").exists()  # normalised inside
    model, _ = load_example("evaluate").load_model(out / "model.zip")
    extractor = model.actor.features_extractor
    assert isinstance(extractor, TaskFrame) and extractor.std.tolist() == pytest.approx(std)
    # SAC from the same demonstrations on the task frame
    out = tmp_path / "sac"
    argv = ["train_sb3.py", "--env-id", "FrankaFCIPush-v0", "--env-kwargs", json.dumps(push)]
    argv += ["--demos", "tests/push-dart-v0", "--features", "task", "--bc-steps", "5"]
    argv += ["--bc-weight", "1", "--num-envs", "2", "--steps", "16", "--evals", "1"]
    argv += ["--eval-episodes", "2", "--net", "16", "--learning-starts", "2", "--no-progress"]
    monkeypatch.setattr("sys.argv", [*argv, "--out", str(out)])
    load_example("train_sb3").main()
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("eval: success_rate=")
    assert not (out / "model" / "vecnormalize.pkl").exists()
    model, _ = load_example("evaluate").load_model(out / "model.zip")
    extractor = model.critic.features_extractor
    assert isinstance(extractor, TaskFrame) and extractor.mean.tolist() == pytest.approx(mean)
