"""The README's example commands, run as documented: `make serve-demo` (the server and
examples/pylibfranka_joint_motion.py through pylibfranka) and examples/scripted.py's
solvers, five episodes of each task (its figures over 200: README, benchmarks/RESULTS.md).
examples/train_sb3.py, evaluate.py, record_video.py and deploy_pylibfranka.py have their
own tests (tests/training, tests/envs/test_env_gymnasium.py, tests/e2e/test_deploy.py)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest

from tests.conftest import ROOT, run_python

SCRIPTED_TASKS = ("FrankaFCIPush-v0", "FrankaFCIPickAndPlace-v0", "FrankaFCIPegInsertion-v0")


@pytest.mark.parametrize("env_id", SCRIPTED_TASKS)
def test_the_scripted_solver_solves_its_task_without_a_reflex(env_id):
    proc = run_python(ROOT / "examples" / "scripted.py", "--env-id", env_id, "--episodes", "5")
    assert proc.returncode == 0, proc.stderr[-3000:]
    last = proc.stdout.strip().splitlines()[-1]
    found = re.fullmatch(
        rf"scripted: env_id={env_id} success_rate=([\d.]+) reflex_rate=([\d.]+)", last
    )
    assert found, proc.stdout
    assert float(found[1]) >= 0.8, last
    assert float(found[2]) == 0.0, proc.stdout


def test_the_push_solver_s_action_is_a_function_of_the_observation():
    # DAgger's labels (examples/train_bc.py --dagger) need it: a fresh solver given each
    # observation of an episode alone acts as the solver did in the episode
    import gymnasium as gym
    import numpy as np

    from tests.conftest import load_example

    scripted = load_example("scripted")
    policy = scripted.ScriptedPolicy("FrankaFCIPush-v0")
    envs = gym.make_vec("FrankaFCIPush-v0", num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = envs.reset(seed=3)
    policy.reset(np.arange(2))
    seen, acted = [], []
    for _ in range(40):  # over the block, down behind it and into the push
        action = policy(obs)
        seen.append({k: v.copy() for k, v in obs.items()})
        acted.append(action)
        obs, *_ = envs.step(action)
    envs.close()
    moved = np.linalg.norm(obs["achieved_goal"] - seen[0]["achieved_goal"], axis=1)
    assert (moved > 0.02).all(), moved  # both blocks pushed by the last steps
    fresh = scripted.ScriptedPolicy("FrankaFCIPush-v0")
    for obs, action in zip(seen, acted, strict=True):
        for arm in range(2):
            fresh.reset(np.arange(1))
            alone = fresh({k: v[arm : arm + 1] for k, v in obs.items()})
            np.testing.assert_array_equal(alone[0], action[arm])


@pytest.mark.socket
def test_make_serve_demo_moves_the_arm_through_pylibfranka():
    make = shutil.which("make")
    assert make, "make is needed (the README's commands are make targets)"
    # The target as a user runs it, with this interpreter (`-o`: the venv is taken as made).
    proc = subprocess.run(
        [make, "-s", "-o", ".venv/.installed", "serve-demo", f"PY={sys.executable}"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert "connected: robot_mode Idle" in out, out[-3000:]
    found = re.search(r"max tracking error (\S+) rad, control_command_success_rate (\S+)", out)
    assert found, out[-3000:]
    assert float(found[2]) > 0.9, found[0]
    assert "motion ended: kSuccess" in out and "motion limit violated" not in out, out[-3000:]
    assert "server stopped" in out  # Ctrl-C stopped it
