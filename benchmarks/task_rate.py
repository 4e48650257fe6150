"""Task throughput: steps/s of each manipulation task, single and batched (N = 64).

    python benchmarks/task_rate.py [--seconds S] [--n 64]

Per task id (its default interface, Cartesian velocity; random actions at 25 Hz, all
checks on, the objects in the scene and the hand mounted): env steps/s of a single env
and of the native batched env at N arms, arm-cycles/s (40 cycles per step), and the
ratio to bare ``mj_step`` of the same worlds (the one-arm world with the task's scene
and hand; N of them, each arm its own MjData, stepped one after the other in a loop)
timed in the same run, just before and just after the env (their mean). Rates are in
this process's CPU time, so that the other processes of a shared host move them little.
Episodes that end (reflex or time limit) are reset, and resets are counted in the time.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import smoke  # benchmarks/smoke.py: --smoke
from env_rate import worlds_step_rate  # benchmarks/env_rate.py, beside this script

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.tasks import TASKS
from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics

#: This process's CPU time (benchmarks/env_rate.py: a shared host's load moves it little).
clock = time.process_time

TASK_IDS = ["FrankaFCIPush-v0", "FrankaFCIPickAndPlace-v0", "FrankaFCIPegInsertion-v0"]
CYCLES = 40


def single_rate(env_id: str, seconds: float) -> float:
    env = gym.make(env_id)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    steps, start = 0, clock()
    while clock() - start < seconds:
        action = rng.uniform(-1, 1, size=env.action_space.shape).astype(np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            env.reset()
    return steps / (clock() - start)


def batched_rate(env_id: str, n: int, seconds: float) -> float:
    """Arm-steps/s of n arms in the native batched env (autoresets included)."""
    env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    shape = env.action_space.shape
    calls, start = 0, clock()
    while clock() - start < seconds:
        env.step(rng.uniform(-1, 1, size=shape).astype(np.float32))
        calls += 1
    return calls * n / (clock() - start)


def bare_rate(env_id: str, n: int, seconds: float) -> float:
    """Arm-cycles/s of bare mj_step on n of the task's one-arm worlds (scene and hand),
    each arm's MjData stepped in turn."""
    task = TASKS[gym.spec(env_id).kwargs["task"]]
    physics = ArmPhysics(n_arms=n, hand=True, scene=task.scene)
    return worlds_step_rate(physics, seconds) * n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--n", type=int, default=64, help="arms of the batched env")
    args = smoke.parse_args(parser, seconds=0.05, n=4)
    print(describe())
    print(f"{'row':<40}{'env steps/s':>12}{'arm-cycles/s':>14}{'vs mj_step':>12}")
    for env_id in TASK_IDS:
        for n in (1, args.n):
            # bare mj_step before and after the env, averaged: a shared host's load drifts
            before = bare_rate(env_id, n, args.seconds / 2)
            if n == 1:
                rate = single_rate(env_id, args.seconds)
                name = f"{env_id}, single"
            else:
                rate = batched_rate(env_id, n, args.seconds)
                name = f"{env_id}, batched N={n}"
            bare = (before + bare_rate(env_id, n, args.seconds / 2)) / 2
            cycles = rate * CYCLES
            print(f"{name:<40}{rate:>12,.0f}{cycles:>14,.0f}{cycles / bare:>12.3f}")
            print(f"{f'  bare mj_step, N={n}':<40}{'':>12}{bare:>14,.0f}{1.0:>12.3f}")


if __name__ == "__main__":
    main()
