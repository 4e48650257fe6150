"""SAC gradient-step time of the default training, by torch thread count.

    python benchmarks/sac_step.py [--steps N] [--repeats R] [--threads T,...] [--busy]

The model of examples/train_sb3.py's default run (SB3's SAC, 16 arms of the batched
env, HER through the reflex-charged buffer, [128, 128] networks, batches of 256)
collects and learns 1,600 samples; then SB3's ``SAC.train`` takes the same N gradient
steps from that same state (model and replay buffer reloaded, seeds reset) under each
thread count (default: 1 and one per core), alternating R times. Prints ms per step
(best of R: a shared host's noise only ever adds time), the ratio to bare mj_step of
the 16-arm world in the same run, and whether every count ended with the same
parameters bit for bit (what lets examples/train_sb3.py's ``--threads`` change the
speed only). A gradient step includes HER's sampling, as in training.

``--busy`` keeps one other process spinning on a core during the timings: what a shared
machine does to a step's parallel regions (why the default run takes one thread).
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
import smoke  # benchmarks/smoke.py: --smoke
import torch as th
from stable_baselines3 import SAC
from stable_baselines3.common.logger import configure

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.native import describe
from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "examples"), str(HERE)]
import train_sb3  # noqa: E402  (examples/train_sb3.py: the default run's model)
from env_rate import bare_rate  # noqa: E402  (benchmarks/env_rate.py, beside this one)

ARMS = 16


def snapshot(directory: Path, env, samples: int = 1_600) -> None:
    """The default run's model after ``samples`` samples, saved with its replay buffer."""
    model = train_sb3.make_model(
        "sac",
        env,
        seed=0,
        log_dir=directory,
        gradient_steps=ARMS,
        learning_starts=ARMS * (train_sb3.DEFAULT_ENV_KWARGS["max_episode_steps"] + 1),
        net=(128, 128),
        buffer_size=12_016,
    )
    model.learn(total_timesteps=samples)
    model.save(directory / "model.zip")
    model.save_replay_buffer(directory / "buffer.pkl")


def timed(directory: Path, env, steps: int, threads: int) -> tuple[float, th.Tensor]:
    """ms per gradient step of ``SAC.train`` from the snapshot with ``threads`` torch
    threads, and the parameters after."""
    model = SAC.load(directory / "model.zip", env=env, device="cpu")
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
    parser.add_argument(
        "--samples", type=int, default=1_600, help="samples the snapshot was trained on"
    )
    parser.add_argument(
        "--threads", default=None, help="torch thread counts, comma-separated (default: 1,cores)"
    )
    parser.add_argument(
        "--busy", action="store_true", help="one other process spins on a core meanwhile"
    )
    args = smoke.parse_args(parser, steps=3, repeats=1, samples=352)
    cores = max(1, os.cpu_count() or 1)
    counts = [int(c) for c in args.threads.split(",")] if args.threads else [1, cores]
    counts = list(dict.fromkeys(counts))
    spec = gym.spec("FrankaFCICartesianVelocity-v0")
    env = FrankaFCISB3VecEnv(ARMS, **{**spec.kwargs, **train_sb3.DEFAULT_ENV_KWARGS})
    bare = 1e3 / bare_rate(ARMS, 0.1 if args.smoke else 1.0)  # ms per mj_step, 16 arms
    best: dict[int, float] = {}
    params: dict[int, th.Tensor] = {}
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        th.set_num_threads(1)
        snapshot(directory, env, args.samples)
        busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.busy else None
        try:
            for _ in range(args.repeats):
                for count in counts:
                    ms, params[count] = timed(directory, env, args.steps, count)
                    best[count] = min(ms, best.get(count, ms))
        finally:
            if busy is not None:
                busy.kill()
                busy.wait()
    first = params[counts[0]]
    same = all(th.equal(first, p) for p in params.values())
    print(describe())
    beside = ", beside a busy process" if args.busy else ""
    runs = f"{args.steps} steps, best of {args.repeats}{beside}"
    print(f"torch {th.__version__}, {cores} cores, {runs}")
    print(f"{'row':<28}{'ms/step':>10}{'vs mj_step':>12}{'vs 1 thread':>13}")
    print(f"{f'bare mj_step, N={ARMS}':<28}{bare:>10.3f}{1.0:>12.1f}{'':>13}")
    one = best.get(1)
    for count, ms in best.items():
        ratio = f"{one / ms:>13.2f}" if one else f"{'':>13}"
        name = f"SB3 SAC.train, {count} thread{'s' if count > 1 else ''}"
        print(f"{name:<28}{ms:>10.3f}{ms / bare:>12.1f}{ratio}")
    print(f"same parameters after every row: {'yes, bit for bit' if same else 'NO'}")
    steps = " ".join(f"step_ms_{c}t={ms:.3f}" for c, ms in best.items())
    print(f"summary: {steps} same_bits={int(same)}")


if __name__ == "__main__":
    main()
