"""examples/train_rllib.py in a reduced form: RLlib's PPO, 2 runners x 2 batched arms, one
iteration, the checkpoint evaluated with the package's evaluation. Skipped where Ray is
not installed (the rllib extra is not part of the test extra)."""

from __future__ import annotations

import json
import re

import pytest

from tests.conftest import ROOT, load_example, run_python

pytest.importorskip("ray.rllib")

LAST = re.compile(
    r"^rllib: env_id=FrankaFCICartesianVelocity-v0 runners=2 envs_per_runner=2 "
    r"env_steps_per_s=(\d+) episode_return_mean=(-?\d+\.\d+)$"
)


def test_two_runners_of_batched_arms_train_and_the_checkpoint_evaluates(tmp_path):
    out = tmp_path / "rllib"
    args = ["--runners", "2", "--envs-per-runner", "2", "--iterations", "1"]
    args += ["--batch-size", "160", "--episodes", "3", "--seed", "1", "--out", str(out)]
    args += ["--env-kwargs", '{"max_episode_steps": 10}']
    proc = run_python(ROOT / "examples" / "train_rllib.py", *args, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.strip().splitlines()
    match = LAST.match(lines[-1])
    assert match, lines[-3:]
    assert int(match.group(1)) > 0
    # 160 steps of 10-step episodes over 4 arms: every arm finished episodes
    assert -11.0 <= float(match.group(2)) <= 0.0
    assert any(line.startswith("evaluate: success_rate=") for line in lines)
    assert (out / "checkpoint").is_dir()
    config = json.loads((out / "train_config.json").read_text())
    trained = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 10, "reward_type": "dense"}
    assert config["env_kwargs"] == trained
    # the checkpoint carries the observation statistics the runners trained behind (RLlib
    # leaves the local runner's at zero; evaluated without them the policy reads raw
    # observations)
    stats = load_example("train_rllib").load_policy(out / "checkpoint").observation_filter
    assert stats is not None and stats.running_stats.n >= 80, stats
    # the checkpoint alone evaluates again, on the env it trained on, to the same figures
    proc = run_python(
        ROOT / "examples" / "train_rllib.py",
        "--evaluate",
        str(out / "checkpoint"),
        "--episodes",
        "3",
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    evaluations = [line for line in proc.stdout.splitlines() if line.startswith("evaluate:")]
    assert evaluations == [line for line in lines if line.startswith("evaluate:")]
