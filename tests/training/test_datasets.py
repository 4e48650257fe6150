"""Demonstrations as Minari datasets (training/datasets.py): recorded from a batched env,
loaded, the env recovered, every episode replayed bit for bit on a single env; bad
input refused with nothing left behind."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

minari = pytest.importorskip("minari")

from franka_sim_gym.training.datasets import (  # noqa: E402
    DEMONSTRATOR_ACTION,
    checked_actions,
    dataset_path,
    episode_seed,
    names,
    record,
    replay,
    summary,
)
from tests.conftest import ROOT, load_example, run_python  # noqa: E402

#: Reach with unfiltered joint-position targets: uniform random actions trip reflexes
#: within a few steps (tests/training/test_sb3_her.py).
REFLEXES = dict(action_filter="none", max_episode_steps=6)
#: Push, short: the scripted solver goes behind the block and starts down
PUSH = dict(max_episode_steps=12)


class RandomPolicy:
    """Uniform actions from a seeded stream (a callable policy, no reset method)."""

    def __init__(self, dim: int, seed: int = 0, scale: float = 1.0) -> None:
        self.rng = np.random.default_rng(seed)
        self.dim, self.scale = dim, scale

    def __call__(self, obs: dict) -> np.ndarray:
        n = len(obs["observation"])
        return self.scale * self.rng.uniform(-1.0, 1.0, (n, self.dim))  # float64: cast


@pytest.fixture(scope="module")
def reflex_dataset(datasets_dir):
    return record(
        "tests/reflexes-v0",
        "FrankaFCI-v0",
        RandomPolicy(7),
        5,
        seed=3,
        env_kwargs=REFLEXES,
        num_envs=3,
    )


@pytest.fixture(scope="module")
def push_dataset(datasets_dir):
    scripted = load_example("scripted")
    policy = scripted.ScriptedPolicy("FrankaFCIPush-v0", env_kwargs=PUSH)
    return record("tests/push-v0", "FrankaFCIPush-v0", policy, 2, seed=7, env_kwargs=PUSH)


def assert_replays(dataset) -> None:
    """Every episode: the recovered single env, reset with the episode's seed and
    stepped with its actions, gives the stored observations, rewards and ends."""
    for episode in dataset.iterate_episodes():
        again = replay(dataset, episode)
        for key, stored in episode.observations.items():
            assert np.array_equal(again["observations"][key], stored), (episode.id, key)
        assert np.array_equal(again["rewards"], episode.rewards)
        assert np.array_equal(again["terminations"], episode.terminations)
        assert np.array_equal(again["truncations"], episode.truncations)


def test_a_batched_recording_loads_and_replays_on_a_single_env(reflex_dataset):
    dataset = minari.load_dataset("tests/reflexes-v0")
    assert dataset.total_episodes == 5
    # arms of two batches (3 + 2): episode k seeded seed + k
    assert [episode_seed(dataset, k) for k in range(5)] == [3, 4, 5, 6, 7]
    spec = dataset.env_spec
    assert spec.id == "FrankaFCI-v0" and spec.max_episode_steps == 6
    assert spec.kwargs["action_filter"] == "none"
    env = dataset.recover_environment()
    assert env.unwrapped.max_episode_steps == 6
    env.close()
    assert_replays(dataset)


def test_reflexes_are_recorded_with_their_names_and_charge(reflex_dataset):
    ended_in_reflex = 0
    for episode in reflex_dataset.iterate_episodes():
        infos = episode.infos
        assert len(infos["is_success"]) == len(episode) + 1  # the reset's info first
        last = names(infos["reflex_reason"][-1])
        if episode.terminations[-1]:
            ended_in_reflex += 1
            assert last, "a terminated episode names the robot's errors"
            charge = infos["reflex_penalty"][-1]
            assert charge < 0  # the worst step reward for each step cut off
            assert episode.rewards[-1] == pytest.approx(-1.0 + charge)
            assert infos["robot_mode"][-1] == b"kReflex"
        else:
            assert last == () and infos["reflex_penalty"][-1] == 0.0
        assert infos["O_F_ext_hat_K"].shape == (len(episode) + 1, 6)
        assert infos["joint_contact"].shape == (len(episode) + 1, 7)
        assert infos["cartesian_contact"].dtype == bool
    assert ended_in_reflex > 0, "random unfiltered actions must trip reflexes"
    success, reflex_rate, reasons = summary(reflex_dataset)
    assert reflex_rate == ended_in_reflex / 5 and success == 0.0
    assert sum(reasons.values()) >= ended_in_reflex


def test_a_scripted_push_records_and_replays(push_dataset):
    assert push_dataset.total_episodes == 2 and push_dataset.total_steps == 24
    assert push_dataset.action_space.shape == (3,)
    assert "algorithm_name" not in push_dataset.storage.metadata
    assert_replays(push_dataset)


def test_scripted_record_writes_a_dataset(datasets_dir):
    proc = run_python(
        ROOT / "examples" / "scripted.py",
        "--env-id",
        "FrankaFCIPush-v0",
        "--episodes",
        "2",
        "--batch",
        "2",
        "--env-kwargs",
        '{"max_episode_steps": 3}',
        "--record",
        "tests/cli-v0",
        "--noise",
        "0.1",
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "recorded 2 episodes as tests/cli-v0" in proc.stdout
    assert proc.stdout.strip().splitlines()[-1].startswith("scripted: env_id=FrankaFCIPush-v0")
    dataset = minari.load_dataset("tests/cli-v0")
    assert dataset.total_steps == 6
    assert dataset.storage.metadata["algorithm_name"] == "examples/scripted.py --noise 0.1"
    for episode in dataset.iterate_episodes():  # the solver's actions kept as the labels
        labels = episode.infos[DEMONSTRATOR_ACTION][1:]
        assert not np.array_equal(episode.actions, labels)
        assert np.abs(episode.actions - labels).max() < 0.6  # sigma 0.1


class Constant:
    """The same action on every arm at every step."""

    def __init__(self, action) -> None:
        self.action = np.asarray(action, dtype=np.float32)

    def __call__(self, obs: dict) -> np.ndarray:
        return np.tile(self.action, (len(obs["observation"]), 1))


#: a slow drift of the TCP, and the noise on its first two axes (DART)
DRIFT, NOISE = [0.1, -0.1, 0.05], [0.1, 0.1, 0.0]


def test_noise_injected_episodes_execute_the_noisy_action_and_keep_the_label(datasets_dir):
    dataset = record(
        "tests/noisy-v0", "FrankaFCIPush-v0", Constant(DRIFT), 3, 5, PUSH, 3, noise=NOISE
    )
    drift = np.asarray(DRIFT, dtype=np.float32)
    deviations = []
    for episode in dataset.iterate_episodes():
        labels = episode.infos[DEMONSTRATOR_ACTION]
        assert np.isnan(labels[0]).all()  # the reset: no action yet
        assert (labels[1:] == drift).all()  # what the policy chose
        assert (episode.actions[:, 2] == drift[2]).all()  # no noise on that axis
        deviations.append(episode.actions[:, :2] - drift[:2])
    deviation = np.concatenate(deviations)
    assert (deviation != 0).all() and 0.05 < deviation.std() < 0.15
    assert_replays(dataset)  # the executed actions replay the episode, bit for bit
    # each episode's noise is drawn from its seed: the same executed actions in other
    # batches (2 + 1 arms instead of 3)
    again = record(
        "tests/noisy-v1", "FrankaFCIPush-v0", Constant(DRIFT), 3, 5, PUSH, 2, noise=NOISE
    )
    for first, second in zip(dataset.iterate_episodes(), again.iterate_episodes(), strict=True):
        assert np.array_equal(first.actions, second.actions)


def test_a_learner_s_episodes_execute_its_actions_and_keep_the_demonstrator_s_labels(
    datasets_dir,
):
    # DAgger's rollouts: the executor acts, the policy labels every state it visits
    scripted = load_example("scripted")
    solver = scripted.ScriptedPolicy("FrankaFCIPush-v0", env_kwargs=PUSH)
    dataset = record(
        "tests/dagger-v0", "FrankaFCIPush-v0", solver, 3, 5, PUSH, 2, executor=Constant(DRIFT)
    )
    labelled = []
    for episode in dataset.iterate_episodes():
        assert (episode.actions == np.asarray(DRIFT, dtype=np.float32)).all()
        labels = episode.infos[DEMONSTRATOR_ACTION]
        assert np.isnan(labels[0]).all()
        # the solver's action at each state the drift reached: the solver run on
        # the stored observations gives the same labels
        solver.reset(np.arange(1))
        for t in range(len(episode)):
            obs = {k: v[t][None] for k, v in episode.observations.items()}
            np.testing.assert_array_equal(labels[t + 1], solver(obs)[0])
        labelled.append(labels[1:])
    assert not np.allclose(np.concatenate(labelled), np.asarray(DRIFT, dtype=np.float32))
    assert_replays(dataset)  # the executed actions replay the episode, bit for bit
    with pytest.raises(
        ValueError, match=r"the executor's action \[2.0, 0.0, 0.0\] \(episode 0\) is outside"
    ):
        record(
            "tests/dagger-bad-v0",
            "FrankaFCIPush-v0",
            solver,
            1,
            0,
            PUSH,
            executor=Constant([2.0, 0.0, 0.0]),
        )
    assert nothing_written("tests/dagger-bad-v0")


def test_without_noise_no_label_is_stored(push_dataset):
    assert DEMONSTRATOR_ACTION not in push_dataset[0].infos


def nothing_written(dataset_id: str) -> bool:
    return not dataset_path(dataset_id).exists() and dataset_id not in minari.list_local_datasets()


@pytest.mark.parametrize(
    "scale, match",
    [
        (1.5, r"the policy's action \[.*\] \(episode 0\) is outside the action space"),
        (np.nan, r"is outside the action space"),
    ],
    ids=["beyond", "nan"],
)
def test_an_action_outside_the_space_is_refused_and_nothing_written(datasets_dir, scale, match):
    with pytest.raises(ValueError, match=match):
        record("tests/bad-v0", "FrankaFCI-v0", RandomPolicy(7, scale=scale), 2, env_kwargs=REFLEXES)
    assert nothing_written("tests/bad-v0")


def test_actions_of_the_wrong_shape_are_refused(datasets_dir):
    with pytest.raises(ValueError, match=r"shape \(2, 3\), expected \(2, 7\)"):
        record("tests/bad-v0", "FrankaFCI-v0", RandomPolicy(3), 2, env_kwargs=REFLEXES)
    assert nothing_written("tests/bad-v0")


def test_an_unknown_env_id_is_refused(datasets_dir):
    with pytest.raises(ValueError, match="unknown env id 'FrankaFCIPushh-v0'"):
        record("tests/bad-v0", "FrankaFCIPushh-v0", RandomPolicy(3), 1)
    assert nothing_written("tests/bad-v0")


def test_an_existing_dataset_is_refused_and_kept(reflex_dataset):
    before = reflex_dataset.total_steps
    with pytest.raises(ValueError, match="dataset 'tests/reflexes-v0' exists"):
        record("tests/reflexes-v0", "FrankaFCI-v0", RandomPolicy(7), 1, env_kwargs=REFLEXES)
    assert minari.load_dataset("tests/reflexes-v0").total_steps == before


@pytest.mark.parametrize(
    "noise, match",
    [
        (-0.1, r"noise must be finite and >= 0, got -0.1"),
        ([0.1, np.nan, 0.1], r"noise must be finite and >= 0"),
        (
            [0.1, 0.1],
            r"noise \[0.1, 0.1\] is neither one standard deviation nor one per action "
            r"dimension \(3\)",
        ),
    ],
    ids=["negative", "nan", "shape"],
)
def test_bad_noise_is_refused_and_nothing_written(datasets_dir, noise, match):
    with pytest.raises(ValueError, match=match):
        record("tests/bad-v0", "FrankaFCIPush-v0", Constant(DRIFT), 2, env_kwargs=PUSH, noise=noise)
    assert nothing_written("tests/bad-v0")


def test_a_malformed_id_and_unstorable_arguments_are_refused(datasets_dir):
    with pytest.raises(ValueError, match="Malformed dataset ID"):
        record("no version", "FrankaFCI-v0", RandomPolicy(7), 1)
    with pytest.raises(ValueError, match="cannot be stored in a dataset"):
        record("tests/bad-v0", "FrankaFCI-v0", RandomPolicy(7), 1, env_kwargs={"x": object()})
    assert nothing_written("tests/bad-v0")


def test_checked_actions_are_a_copy_of_the_policy_s_array():
    """A policy that reuses one output array must not rewrite the steps already stored."""
    space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
    out = np.zeros((2, 3), np.float32)
    stored = checked_actions(out, space, np.arange(2))
    out[...] = 0.5
    assert (stored == 0.0).all()
