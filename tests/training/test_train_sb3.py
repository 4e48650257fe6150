"""examples/train_sb3.py and examples/evaluate.py end to end; SB3's env checker on every id."""

from __future__ import annotations

import csv
import json

import gymnasium as gym
import pytest

import franka_sim_gym  # noqa: F401
from franka_sim_gym.envs import IDS
from tests.conftest import ROOT, run_python

sb3 = pytest.importorskip("stable_baselines3")

from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer  # noqa: E402


@pytest.mark.parametrize("env_id", list(IDS))
def test_sb3_check_env_passes_for_every_id(env_id):
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(env_id)
    check_env(env.unwrapped, warn=True)
    env.close()


@pytest.mark.parametrize("arms", [["--num-envs", "1"], []], ids=["single", "batched"])
def test_train_sb3_runs_end_to_end_and_evaluate_reads_what_it_saved(tmp_path, arms):
    out = tmp_path / "run"
    proc = run_python(
        ROOT / "examples" / "train_sb3.py",
        *arms,
        "--steps",
        "400",
        "--evals",
        "1",
        "--eval-episodes",
        "2",
        "--out",
        str(out),
        "--env-kwargs",
        '{"max_episode_steps": 10}',
        "--tensorboard",
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    last = proc.stdout.strip().splitlines()[-1]
    assert last.startswith("eval: success_rate=") and "reflex_rate=" in last
    assert (out / "model.zip").is_file() and (out / "eval.csv").is_file()
    assert (out / "progress.csv").is_file()
    assert list(out.glob("events.out.tfevents.*")), "no TensorBoard events were written"
    assert "training: 100%" in proc.stderr and "400/400" in proc.stderr  # the progress bar
    config = json.loads((out / "train_config.json").read_text())
    assert config["env_id"] == "FrankaFCICartesianVelocity-v0"
    assert config["env_kwargs"] == {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 10}
    env = gym.make(config["env_id"], **config["env_kwargs"])
    model = sb3.SAC.load(out / "model.zip", env=env)  # HER needs the env
    # HER keeps the reflex charge (training/sb3_her.py); the buffer holds the run, no more
    assert model.replay_buffer_class is ReflexChargedHerReplayBuffer
    assert model.buffer_size == (401 if arms else 416)  # 400 samples and a spare step
    assert model.ent_coef == "auto_0.02"
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action) and action.shape == (3,)
    # evaluate.py takes the env id and arguments from train_config.json.
    proc = run_python(
        ROOT / "examples" / "evaluate.py", "--model", str(out / "model.zip"), "--episodes", "3"
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    last = proc.stdout.strip().splitlines()[-1]
    assert last.startswith("evaluate: success_rate=") and "link_success_rate=" in last


def test_train_sb3_normalizes_observations_and_stops_at_its_time_limit(tmp_path):
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from franka_sim_gym.training.sb3_zoo import NormalizedPolicy, with_normalization

    out = tmp_path / "run"
    args = ["--steps", "640", "--eval-every", "320", "--time-limit", "0", "--eval-episodes", "2"]
    args += ["--normalize", "--no-progress", "--out", str(out)]
    proc = run_python(
        ROOT / "examples" / "train_sb3.py", *args, "--env-kwargs", '{"max_episode_steps": 10}'
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert "time limit of 0 s reached at 320 samples" in lines
    assert lines[-1].startswith("eval: success_rate=")
    # one evaluation (the time limit stopped the run after it), its reflexes by error
    rows = list(csv.DictReader((out / "eval.csv").open()))
    assert [row["steps"] for row in rows] == ["320"]
    assert isinstance(json.loads(rows[0]["reflexes_by_error"]), dict)
    assert float(rows[0]["wall_s"]) > 0
    # the statistics where examples/evaluate.py looks for them, updated by the training
    config = json.loads((out / "train_config.json").read_text())
    env = gym.make(config["env_id"], **config["env_kwargs"])
    stats = VecNormalize.load(str(out / "model" / "vecnormalize.pkl"), DummyVecEnv([lambda: env]))
    assert stats.norm_obs and not stats.norm_reward
    assert stats.obs_rms["observation"].count > 320
    model = sb3.SAC.load(out / "model.zip", env=env)
    assert isinstance(with_normalization(model, out / "model.zip", env), NormalizedPolicy)


def test_the_default_recipe_learns_the_reach_in_3000_samples(tmp_path):
    """make demo's recipe, cut to 3,000 samples (~50 s of one core): a recipe that stopped
    learning fails here. The recipe as it is reached 0.94 with seed 0 (0.78-1.00 over
    seeds 0-4 at 3,000 samples, docs/training.md); without the observation normalisation
    (the recipe before, whose seed 0 collapsed) it reached 0.19, and a policy that learns
    nothing (the recipe at 1,000 samples) 0.00-0.06."""
    out = tmp_path / "run"
    args = ["--steps", "3000", "--evals", "1", "--seed", "0", "--no-progress", "--out", str(out)]
    proc = run_python(ROOT / "examples" / "train_sb3.py", *args, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    row = next(csv.DictReader((out / "eval.csv").open()))
    assert float(row["success_rate"]) >= 0.5, row
    assert float(row["reflex_rate"]) <= 0.1, row


def test_the_actor_options_of_sac_are_refused_for_td3(tmp_path):
    script = ROOT / "examples" / "train_sb3.py"
    for flags in (["--bc-steps", "10", "--bc-std", "0.1"], ["--actor-warmup", "10"]):
        args = ["--algo", "td3", "--demos", "me/none-v0", *flags, "--out", str(tmp_path)]
        proc = run_python(script, *args, timeout=60)
        assert proc.returncode == 2
        assert "act on SAC's actor, not --algo td3" in proc.stderr
