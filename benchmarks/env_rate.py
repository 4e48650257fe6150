"""Env throughput: steps/s of FrankaFCI-v0 with random actions at a 25 Hz policy.

    python benchmarks/env_rate.py [--seconds S] [--shares]

One row per action interface (single env, libfranka's rate-limited client, all
checks on), with cycles/s (40 cycles per step) and the ratio to bare mj_step of
the same one-arm world in the same run, rates in this process's CPU time. Episodes
that end (reflex or time limit) are reset, and resets are counted in the time.

Then the native batched vector env (joint position) at N = 16 and 64 arms (each arm its
own MjData of the one-arm world): env steps/s and arm-cycles/s (one core), the ratio to
N single envs in a Gymnasium SyncVectorEnv, and to bare mj_step of the same N one-arm
worlds, stepped one after the other in a loop.

With ``--shares``, a second table: for each interface (and the batched env at N = 64),
the share of the env step's wall time spent in the client's filters
(``CommandGenerator.command``) and in ``ArmKinematics.solve`` (zero where the
controller solves through a fused kernel of its own), timed around those calls.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np
import smoke  # benchmarks/smoke.py: --smoke

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.commands import INTERFACES, CommandGenerator
from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.kinematics import ArmKinematics

#: The time the rates are counted in: this process's CPU time, so that the other
#: processes of a shared host move the figures little (a wall clock counts their
#: share of the cores too). On an idle core the two agree.
clock = time.process_time


def env_rate(interface: str, seconds: float) -> tuple[float, int]:
    env = gym.make("FrankaFCI-v0", action_interface=interface)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    steps, resets, start = 0, 0, clock()
    while clock() - start < seconds:
        action = rng.uniform(-1, 1, size=env.action_space.shape).astype(np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            env.reset()
            resets += 1
    return steps / (clock() - start), resets


def vector_rate(n: int, mode: str, seconds: float) -> float:
    """Env steps/s (arm-steps: n per call) of n arms, batched or in a SyncVectorEnv."""
    env = gym.make_vec("FrankaFCI-v0", num_envs=n, vectorization_mode=mode)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    calls, start = 0, clock()
    while clock() - start < seconds:
        env.step(rng.uniform(-1, 1, size=(n, 7)).astype(np.float32))  # autoresets included
        calls += 1
    return calls * n / (clock() - start)


def worlds_step_rate(physics: ArmPhysics, seconds: float) -> float:
    """Cycles/s of bare mj_step on every arm's one-arm world in turn (one cycle: each
    arm's MjData stepped once), in this process's CPU time."""
    model, datas = physics.model, physics.datas
    calls, start = 0, clock()
    while clock() - start < seconds:
        for _ in range(20):
            for data in datas:
                mujoco.mj_step(model, data)
        calls += 20
    return calls / (clock() - start)


def bare_rate(n: int, seconds: float) -> float:
    """Cycles/s of n one-arm worlds: mj_step on each arm's MjData in a loop."""
    return worlds_step_rate(ArmPhysics(n_arms=n), seconds)


class _Timed:
    """Wall time spent inside a method, summed over calls (a wrapper on the class)."""

    def __init__(self, cls: type, name: str) -> None:
        self.cls, self.name, self.original, self.seconds = cls, name, getattr(cls, name), 0.0
        timed, original = self, self.original

        def wrapper(*args, **kwargs):
            start = clock()
            try:
                return original(*args, **kwargs)
            finally:
                timed.seconds += clock() - start

        setattr(cls, name, wrapper)

    def restore(self) -> None:
        setattr(self.cls, self.name, self.original)


def shares(seconds: float) -> None:
    """The client filters' and the IK's share of the env step, per interface."""
    filters = _Timed(CommandGenerator, "command")
    ik = _Timed(ArmKinematics, "solve")
    print(f"{'share of an env step':<34}{'steps/s':>10}{'filters':>10}{'IK':>8}")
    rows = [(name, lambda name=name: env_rate(name, seconds)[0]) for name in INTERFACES]
    rows.append(("batched, N=64", lambda: vector_rate(64, "vector_entry_point", seconds)))
    for name, run in rows:
        filters.seconds = ik.seconds = 0.0
        start = clock()
        rate = run()
        total = clock() - start
        print(f"{name:<34}{rate:>10,.0f}{filters.seconds / total:>10.1%}{ik.seconds / total:>8.1%}")
    filters.restore()
    ik.restore()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--shares", action="store_true", help="time the filters and the IK")
    parser.add_argument(
        "--arms", type=int, nargs="+", default=[16, 64], help="N of the batched rows"
    )
    args = smoke.parse_args(parser, seconds=0.05, shares=True, arms=[2, 4])
    physics = ArmPhysics(n_arms=1)
    calls, start = 0, clock()
    while clock() - start < args.seconds:
        for _ in range(100):
            mujoco.mj_step(physics.model, physics.data)
        calls += 100
    bare = calls / (clock() - start)
    print(describe())
    print(f"{'row':<34}{'steps/s':>10}{'cycles/s':>12}{'vs mj_step':>12}{'resets':>8}")
    print(f"{'bare mj_step (one arm)':<34}{'':>10}{bare:>12,.0f}{1.0:>12.2f}{'':>8}")
    rates = {}
    for interface in INTERFACES:
        steps, resets = env_rate(interface, args.seconds)
        rates[interface] = steps
        cycles = steps * 40
        print(f"{interface:<34}{steps:>10,.0f}{cycles:>12,.0f}{cycles / bare:>12.3f}{resets:>8}")
    print()
    print(
        f"{'batched (joint position)':<26}{'env steps/s':>12}{'arm-cycles/s':>14}"
        f"{'vs Sync':>9}{'vs mj_step':>12}"
    )
    batched = {}
    for n in args.arms:
        bare = bare_rate(n, args.seconds) * n  # arm-steps/s
        sync = vector_rate(n, "sync", args.seconds)
        steps = batched[n] = vector_rate(n, "vector_entry_point", args.seconds)
        for name, rate in ((f"SyncVectorEnv, N={n}", sync), (f"batched, N={n}", steps)):
            print(
                f"{name:<26}{rate:>12,.0f}{rate * 40:>14,.0f}"
                f"{rate / sync:>9.1f}{rate * 40 / bare:>12.3f}"
            )
        print(f"{f'bare mj_step, N={n}':<26}{'':>12}{bare:>14,.0f}{'':>9}{1.0:>12.3f}")
    print(
        f"summary: env_steps_per_s={rates['joint_position']:.0f} "
        f"cycles_per_s={rates['joint_position'] * 40:.0f} "
        f"batched_arm_cycles_per_s={batched[args.arms[-1]] * 40:.0f}"
    )
    if args.shares:
        print()
        shares(args.seconds)


if __name__ == "__main__":
    main()
