"""What a reality profile costs: env steps/s under each profile against the ideal robot.

    python benchmarks/reality_rate.py [--seconds S] [--rounds R] [--id ID]

Rows: the single env and the batched env (N = 16, 64), each under ``ideal``, ``fr3`` and
``randomized`` (random actions, all checks on, resets counted), with the ratio to bare
mj_step of as many bare one-arm worlds (no scene) and to ideal. Rates are in this
process's CPU time; the profiles of a row are measured in turn, ``--rounds`` times: the
rate is the best round's, the ratio to ideal the median over the rounds of each round's
ratio (a shared host's load drifts between rounds, less within one).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import smoke  # benchmarks/smoke.py: --smoke

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics

clock = time.process_time
PROFILES = ("ideal", "fr3", "randomized")


def steps_per_s(env_id: str, n: int | None, profile: str, seconds: float) -> float:
    """Env steps/s (arm-steps for a batch) of random actions."""
    if n is None:
        env = gym.make(env_id, reality=profile)
        env.reset(seed=0)
    else:
        env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                           reality=profile)  # fmt: skip
        env.reset(seed=0)
    rng = np.random.default_rng(0)
    shape = env.action_space.shape
    steps, start = 0, clock()
    while clock() - start < seconds:
        out = env.step(rng.uniform(-1, 1, size=shape).astype(np.float32))
        steps += 1 if n is None else n
        if n is None and (out[2] or out[3]):
            env.reset()
    return steps / (clock() - start)


def bare_arm_cycles(n: int, seconds: float) -> float:
    """Arm-cycles/s of mj_step on n one-arm worlds in turn."""
    import mujoco

    physics = ArmPhysics(n_arms=n)
    calls, start = 0, clock()
    while clock() - start < seconds:
        for data in physics.datas:
            mujoco.mj_step(physics.model, data)
        calls += 1
    return calls * n / (clock() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--id", default="FrankaFCI-v0", help="env id (default FrankaFCI-v0)")
    args = smoke.parse_args(parser, seconds=0.2, rounds=1)
    cycles = gym.spec(args.id).kwargs.get("policy_hz", 25)
    cycles = round(1000 / cycles)
    print(describe())
    print(f"{args.id}, {cycles} cycles a step; {args.rounds} rounds of {args.seconds:g} s each")
    print(f"{'row':<22}{'profile':<12}{'steps/s':>10}{'arm-cycles/s':>14}"
          f"{'vs mj_step':>12}{'vs ideal':>10}")  # fmt: skip
    for n in (None, 16, 64):
        bare = bare_arm_cycles(n or 1, args.seconds)
        rounds = []
        for _ in range(args.rounds):
            rounds.append({p: steps_per_s(args.id, n, p, args.seconds) for p in PROFILES})
        row = "single env" if n is None else f"batched, N={n}"
        for profile in PROFILES:
            rate = max(r[profile] for r in rounds)
            ratio = float(np.median([r[profile] / r["ideal"] for r in rounds]))
            print(
                f"{row:<22}{profile:<12}{rate:>10,.0f}{rate * cycles:>14,.0f}"
                f"{rate * cycles / bare:>12.3f}{ratio:>10.3f}"
            )


if __name__ == "__main__":
    main()
