"""SAC gradient-step time of the default training: SB3's SAC.train against LeanSAC.

    python benchmarks/sac_step.py [--steps N] [--repeats R] [--threads T] [--busy]

The model of examples/train_sb3.py's default run (16 arms of the batched env, HER
through the reflex-charged buffer, [128, 128] networks, batches of 256) collects and
learns 1,600 samples; then both ``train`` methods take the same N gradient steps from
that same state (model and replay buffer reloaded, seeds reset), alternating R times.
Prints ms per step (best of R: a shared host's noise only ever adds time), the ratio
to bare mj_step of the 16-arm world in the same run, and whether both ended with the
same parameters bit for bit (they must: envs/sb3_sac.py). A gradient step includes
HER's sampling, as in training.

On a machine of several cores a third row takes LeanSAC's steps with one torch thread
(the other choice of envs/sb3_threads.py's ThreadTuner; the same bits too), and
``--busy`` keeps one other process spinning on a core during the timings: what a shared
machine does to a step's parallel regions.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3 import SAC
from stable_baselines3.common.logger import configure

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.sb3_sac import LeanSAC
from franka_sim_gym.envs.sb3_vec_env import FrankaFCISB3VecEnv
from franka_sim_gym.native import describe

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "examples"), str(HERE)]
import train_sb3  # noqa: E402  (examples/train_sb3.py: the default run's model)
from env_rate import bare_rate  # noqa: E402  (benchmarks/env_rate.py, beside this one)

ARMS = 16


def snapshot(directory: Path, env, threads: int) -> None:
    """The default run's model after 1,600 samples, saved with its replay buffer."""
    model = train_sb3.make_model(
        "sac",
        env,
        seed=0,
        log_dir=directory,
        gradient_steps=ARMS,
        learning_starts=ARMS * (train_sb3.DEFAULT_ENV_KWARGS["max_episode_steps"] + 1),
        net=(128, 128),
        buffer_size=12_016,
        threads=threads,
    )
    model.learn(total_timesteps=1_600)
    model.save(directory / "model.zip")
    model.save_replay_buffer(directory / "buffer.pkl")


def timed(algo, directory: Path, env, steps: int, threads: int) -> tuple[float, th.Tensor]:
    """ms per gradient step of ``algo.train`` from the snapshot with ``threads`` torch
    threads, and the parameters after."""
    model = algo.load(directory / "model.zip", env=env, device="cpu")
    th.set_num_threads(threads)
    # as saved: the arms' unfinished episodes are not sampled (HER needs their ends)
    model.load_replay_buffer(directory / "buffer.pkl", truncate_last_traj=False)
    model.set_logger(configure(str(directory), []))  # train() records its losses
    th.manual_seed(0)
    np.random.seed(0)  # HER samples with numpy's global generator
    start = time.perf_counter()
    model.train(gradient_steps=steps, batch_size=model.batch_size)
    ms = (time.perf_counter() - start) / steps * 1e3
    return ms, th.cat([p.detach().flatten() for p in model.policy.parameters()])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="gradient steps per timing")
    parser.add_argument("--repeats", type=int, default=6)
    parser.add_argument("--threads", type=int, default=None, help="torch threads")
    parser.add_argument(
        "--busy", action="store_true", help="one other process spins on a core meanwhile"
    )
    args = parser.parse_args()
    threads = args.threads or max(1, os.cpu_count() or 1)
    spec = gym.spec("FrankaFCICartesianVelocity-v0")
    env = FrankaFCISB3VecEnv(ARMS, **{**spec.kwargs, **train_sb3.DEFAULT_ENV_KWARGS})
    bare = 1e3 / bare_rate(ARMS, 1.0)  # ms per mj_step of the 16-arm world
    rows = [("SB3 SAC.train", SAC, threads), ("LeanSAC.train", LeanSAC, threads)]
    if threads > 1:
        rows.append(("LeanSAC.train, 1 thread", LeanSAC, 1))
    best: dict[str, float] = {}
    params: dict[str, th.Tensor] = {}
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        snapshot(directory, env, threads)
        busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.busy else None
        try:
            for _ in range(args.repeats):
                for name, algo, count in rows:
                    ms, params[name] = timed(algo, directory, env, args.steps, count)
                    best[name] = min(ms, best.get(name, ms))
        finally:
            if busy is not None:
                busy.kill()
                busy.wait()
    first = params["SB3 SAC.train"]
    same = all(th.equal(first, p) for p in params.values())
    print(describe())
    beside = ", beside a busy process" if args.busy else ""
    print(f"torch {th.__version__}, {threads} threads, {args.steps} steps{beside}")
    print(f"{'row':<26}{'ms/step':>10}{'vs mj_step':>12}{'vs SB3':>9}")
    print(f"{f'bare mj_step, N={ARMS}':<26}{bare:>10.3f}{1.0:>12.1f}{'':>9}")
    sb3 = best["SB3 SAC.train"]
    for name, ms in best.items():
        print(f"{name:<26}{ms:>10.3f}{ms / bare:>12.1f}{sb3 / ms:>9.2f}")
    print(f"same parameters after every row: {'yes, bit for bit' if same else 'NO'}")
    print(
        f"summary: sb3_step_ms={sb3:.3f} lean_step_ms={best['LeanSAC.train']:.3f} "
        f"speedup={sb3 / best['LeanSAC.train']:.2f} same_bits={int(same)}"
    )


if __name__ == "__main__":
    main()
