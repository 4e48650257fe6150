"""SAC with an imitation policy beside its actor (training/ibrl.py): the critics choose
each arm's action and each bootstrap's proposal; examples/train_sb3.py --imitation end to
end, the run saved without the imitation policy and loaded back with it."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

minari = pytest.importorskip("minari")
sb3 = pytest.importorskip("stable_baselines3")

import torch as th  # noqa: E402

from franka_sim_gym.training.datasets import record  # noqa: E402
from franka_sim_gym.training.ibrl import ImitationBootstrappedSAC  # noqa: E402
from tests.conftest import load_example  # noqa: E402
from tests.scripted_policies import TowardTheGoal  # noqa: E402
from tests.training.test_sb3_demos import one_thread  # noqa: E402, F401

ENV_ID = "FrankaFCICartesianVelocity-v0"
#: train_sb3.py's default run, short
KWARGS = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 6}


def observations(n: int) -> dict[str, np.ndarray]:
    """n reset observations (seeds 0 ... n-1), stacked as a batched env's."""
    env = gym.make(ENV_ID, **KWARGS)
    rows = [env.reset(seed=seed)[0] for seed in range(n)]
    env.close()
    return {k: np.stack([row[k] for row in rows]) for k in rows[0]}


def model() -> ImitationBootstrappedSAC:
    env = gym.make(ENV_ID, **KWARGS)
    return ImitationBootstrappedSAC(
        "MultiInputPolicy", env, buffer_size=10, seed=0, policy_kwargs=dict(net_arch=[16])
    )


def critics_value(critic, sac, obs: dict, actions: np.ndarray) -> np.ndarray:
    """The twin critics' minimum for env-unit actions, computed here."""
    tensors, _ = sac.policy.obs_to_tensor(obs)
    scaled = th.as_tensor(sac.policy.scale_action(actions), dtype=th.float32)
    with th.no_grad():
        q1, q2 = critic(tensors, scaled)
    return th.minimum(q1, q2).reshape(-1).numpy()


def test_acting_takes_per_arm_the_action_the_critics_value_higher():
    sac = model()
    obs = observations(32)
    own = sb3.SAC.predict(sac, obs, deterministic=True)[0]
    np.testing.assert_array_equal(sac.predict(obs, deterministic=True)[0], own)  # no imitation
    sac.imitation = TowardTheGoal()
    imitated = TowardTheGoal().predict(obs)[0]
    take = critics_value(sac.critic, sac, obs, imitated) > critics_value(sac.critic, sac, obs, own)
    assert 0 < take.sum() < len(take)  # the untrained critics prefer either here and there
    chosen, _ = sac.predict(obs, deterministic=True)
    np.testing.assert_array_equal(chosen, np.where(take[:, None], imitated, own))
    one, _ = sac.predict({k: v[0] for k, v in obs.items()}, deterministic=True)
    assert one.shape == (3,)
    np.testing.assert_array_equal(one, chosen[0])


def test_the_bootstrap_takes_the_better_of_the_actors_and_the_imitations_proposal():
    sac = model()
    sac.imitation = TowardTheGoal()
    obs = observations(32)
    tensors, _ = sac.policy.obs_to_tensor(obs)
    ent_coef = th.tensor([0.05])
    th.manual_seed(7)
    with th.no_grad():
        value = sac.next_value(tensors, ent_coef).numpy()
    th.manual_seed(7)  # the actor's same sampled proposals
    with th.no_grad():
        proposed, log_prob = sac.actor.action_log_prob(tensors)
        q1, q2 = sac.critic_target(tensors, proposed)
        own = (th.minimum(q1, q2).reshape(-1) - 0.05 * log_prob.reshape(-1)).numpy()
    imitated = critics_value(sac.critic_target, sac, obs, TowardTheGoal().predict(obs)[0])
    assert (imitated > own).any() and (own > imitated).any()
    np.testing.assert_allclose(value, np.maximum(own, imitated), rtol=1e-6)


def test_training_is_sacs_with_the_bootstrap_from_next_value():
    """One gradient step from the same state and batch: with the actor's own value as
    ``next_value`` it is SAC's step, bit for bit; with ``next_value`` raised, the critics
    move elsewhere (the target is taken from it)."""
    from franka_sim_gym.training.ibrl import lowest

    def stepped(shift: float | None) -> list[th.Tensor]:
        sac = model()
        sac.learning_starts = 40
        sac.learn(total_timesteps=30)  # fills the buffer; no gradient step yet
        sac.imitation = TowardTheGoal()

        def own(obs, ent_coef):  # SAC's next value: the actor's proposal only
            actions, log_prob = sac.actor.action_log_prob(obs)
            value = lowest(sac.critic_target, obs, actions) - ent_coef.reshape(()) * log_prob
            return value + shift

        if shift is not None:
            sac.next_value = own
        sac.replay_buffer.sample = _seeded(sac.replay_buffer.sample)
        th.manual_seed(3)
        (sac.train if shift is not None else lambda n, b: sb3.SAC.train(sac, n, b))(1, 16)
        return [p.detach().clone() for p in sac.critic.parameters()]

    plain = stepped(None)
    assert all(th.equal(a, b) for a, b in zip(plain, stepped(0.0), strict=True))
    assert not all(th.equal(a, b) for a, b in zip(plain, stepped(10.0), strict=True))


def _seeded(sample):
    """The buffer's sample with numpy's global generator seeded (SB3 draws from it)."""

    def draw(*args, **kwargs):
        np.random.seed(5)
        return sample(*args, **kwargs)

    return draw


def test_train_sb3_with_an_imitation_run_saves_without_it_and_loads_with_it(
    datasets_dir, tmp_path, monkeypatch, capsys
):
    record("tests/ibrl-v0", ENV_ID, lambda obs: TowardTheGoal().predict(obs)[0], 4, 0, KWARGS)
    bc = tmp_path / "bc"
    argv = ["train_bc.py", "--demos", "tests/ibrl-v0", "--steps", "20", "--net", "16"]
    monkeypatch.setattr("sys.argv", [*argv, "--eval-episodes", "2", "--out", str(bc)])
    load_example("train_bc").main()
    capsys.readouterr()
    out = tmp_path / "ibrl"
    argv = ["train_sb3.py", "--env-id", ENV_ID, "--env-kwargs", json.dumps(KWARGS)]
    argv += ["--demos", "tests/ibrl-v0", "--num-envs", "2", "--steps", "16", "--evals", "1"]
    argv += ["--eval-episodes", "2", "--net", "16", "--learning-starts", "2", "--no-progress"]
    argv += ["--no-normalize"]
    # another algorithm, or a policy of another env: refused before any step
    for extra, message in (
        (["--algo", "td3", "--imitation", str(bc)], "not --algo td3"),
        (["--imitation", str(tmp_path / "none")], "without a model.zip"),
        (["--imitation", str(tmp_path / "typo")], "no such run folder or model.zip"),
        (["--imitation", str(bc), "--sde"], "--imitation trains SAC without --sde"),
        (["--imitation", str(bc), "--normalize"], "give --features task or --no-normalize"),
    ):
        (tmp_path / "none").mkdir(exist_ok=True)
        monkeypatch.setattr("sys.argv", [*argv, *extra, "--out", str(out)])
        with pytest.raises(SystemExit):
            load_example("train_sb3").main()
        assert message in capsys.readouterr().err
    other = [*argv, "--imitation", str(bc), "--out", str(out)]
    other[other.index("--env-kwargs") + 1] = json.dumps({**KWARGS, "cartesian_dof": 6})
    monkeypatch.setattr("sys.argv", other)
    with pytest.raises(SystemExit):
        load_example("train_sb3").main()
    assert "whose spaces are not this run's" in capsys.readouterr().err
    monkeypatch.setattr("sys.argv", [*argv, "--imitation", str(bc), "--out", str(out)])
    load_example("train_sb3").main()
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("eval: success_rate=")
    config = json.loads((out / "train_config.json").read_text())
    assert config["imitation"] == str(bc.resolve())
    # the zip holds SAC's parts only; evaluate.py attaches the named run (its folder given)
    saved = ImitationBootstrappedSAC.load(out / "model.zip", env=gym.make(ENV_ID, **KWARGS))
    assert saved.imitation is None
    loaded, settings = load_example("evaluate").load_model(out)
    assert isinstance(loaded, ImitationBootstrappedSAC) and settings["env_id"] == ENV_ID
    clone, _ = load_example("evaluate").load_model(bc / "model.zip")
    obs = observations(4)
    np.testing.assert_array_equal(loaded.imitation.predict(obs)[0], clone.predict(obs)[0])
