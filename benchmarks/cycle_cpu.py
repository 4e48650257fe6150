"""Process time of one controller cycle, per generator, for A/B comparisons on a busy host.

    python benchmarks/cycle_cpu.py [--arms 1 16] [--cycles 3000] [--repeats 3] [--rotate]

Rows: a joint-position, a Cartesian-pose and a Cartesian-velocity motion streamed
in-process (cycle_rate.py's streams: a 4 s cosine on joint 4, or of 5 cm along x),
each the best of ``--repeats`` runs of ``--cycles`` cycles in ``time.process_time``
(CPU time: other processes on the host barely move it, unlike wall-clock rates), and
bare ``mujoco.mj_step`` of the same world timed the same way: "vs mj_step" is the
ratio of the two CPU times, cycle_rate.py's ratio without the host's noise.
``--rotate`` adds a 0.1 rad turn about z (and back) to the Cartesian streams, so the rotation
paths (the pose's rotation log, the twist's exponential) are timed too.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import smoke  # benchmarks/smoke.py: --smoke
from cycle_rate import (
    CARTESIAN_POSITION,
    CARTESIAN_VELOCITY,
    JOINT_POSITION,
    motion,
)

from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics


def cycle_cpu(cycle, cycles: int, repeats: int) -> float:
    """Best process time of one call of ``cycle`` [s] over ``repeats`` runs."""
    for _ in range(200):
        cycle()
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        for _ in range(cycles):
            cycle()
        best = min(best, (time.process_time() - start) / cycles)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", type=int, nargs="+", default=[1, 16])
    parser.add_argument("--cycles", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rotate", action="store_true", help="turn the Cartesian streams")
    args = smoke.parse_args(parser, cycles=20, repeats=1)
    generators = {
        "joint position": JOINT_POSITION,
        "Cartesian pose": CARTESIAN_POSITION,
        "Cartesian velocity": CARTESIAN_VELOCITY,
    }
    print(describe())
    print(f"{'row':<32}{'us/cycle':>10}{'vs joint':>10}{'vs mj_step':>12}")
    for n in args.arms:
        physics = ArmPhysics(n_arms=n)
        bare = cycle_cpu(  # n one-arm worlds: each arm's MjData stepped in turn
            lambda p=physics: [mujoco.mj_step(p.model, d) for d in p.datas],
            args.cycles,
            args.repeats,
        )
        print(f"{f'bare mj_step, n={n}':<32}{bare * 1e6:>10.1f}{'':>10}{1.0:>12.3f}")
        joint = None
        for name, generator in generators.items():
            cpu = cycle_cpu(motion(n, generator, args.rotate)[1], args.cycles, args.repeats)
            joint = joint or cpu
            row = f"{name}, n={n}"
            print(f"{row:<32}{cpu * 1e6:>10.1f}{cpu / joint:>10.2f}{bare / cpu:>12.3f}")


if __name__ == "__main__":
    main()
