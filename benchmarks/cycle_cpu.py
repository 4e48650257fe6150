"""Process time of one controller cycle, per generator, for A/B comparisons on a busy host.

    python benchmarks/cycle_cpu.py [--arms 1 16] [--cycles 3000] [--repeats 3] [--rotate]

Rows: a joint-position, a Cartesian-pose and a Cartesian-velocity motion streamed
in-process (cycle_rate.py's streams: a 4 s cosine on joint 4, or of 5 cm along x),
each the best of ``--repeats`` runs of ``--cycles`` cycles in ``time.process_time``
(CPU time: other processes on the host barely move it, unlike wall-clock rates).
``--rotate`` adds a 0.1 rad turn about z (and back) to the Cartesian streams, so the rotation
paths (the pose's rotation log, the twist's exponential) are timed too.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from cycle_rate import (
    CARTESIAN_POSITION,
    CARTESIAN_VELOCITY,
    IMPEDANCE,
    JOINT_POSITION,
    streaming_cycle,
)

from franka_sim_gym.fci.config import ControllerConfig
from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.sim.arm import ArmPhysics

PERIOD = 4000


def _turn(angle: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rotations about z."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((len(angle), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def motion(n: int, generator, rotate: bool):
    """A started controller and its streaming cycle (one command per arm per call)."""
    ctrl = FciController(ArmPhysics(n_arms=n), ControllerConfig())
    for i in range(n):
        ctrl.move(i, int(IMPEDANCE), int(generator))
    for _ in range(2):
        ctrl.step()
    t = np.arange(PERIOD) * 1e-3
    bump = 1 - np.cos(2 * np.pi * t / 4.0)  # 0 .. 2 .. 0 over the period
    rate = np.sin(2 * np.pi * t / 4.0) * 2 * np.pi / 4.0  # its derivative
    if generator == CARTESIAN_POSITION:
        pose0 = ctrl.states["O_T_EE_d"].astype(np.float64)
        waypoints = np.repeat(pose0[None], PERIOD, axis=0)
        waypoints[:, :, 12] += (0.025 * bump)[:, None]
        if rotate:  # R0 Rz(turn), written column-major (the wire's R^T block)
            R0 = pose0.reshape(n, 4, 4).transpose(0, 2, 1)[:, :3, :3]
            R = np.einsum("nab,tbc->tnac", R0, _turn(0.05 * bump))
            waypoints.reshape(PERIOD, n, 4, 4)[:, :, :3, :3] = R.transpose(0, 1, 3, 2)
        return streaming_cycle(ctrl, "O_T_EE_c", waypoints)
    if generator == CARTESIAN_VELOCITY:
        waypoints = np.zeros((PERIOD, n, 6))
        waypoints[:, :, 0] = (0.025 * rate)[:, None]
        if rotate:
            waypoints[:, :, 5] = (0.05 * rate)[:, None]
        return streaming_cycle(ctrl, "O_dP_EE_c", waypoints)
    q0 = ctrl.states["q_d"].astype(np.float64)
    waypoints = np.repeat(q0[None], PERIOD, axis=0)
    waypoints[:, :, 3] += (0.1 * bump)[:, None]
    return streaming_cycle(ctrl, "q_c", waypoints)


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
    args = parser.parse_args()
    generators = {
        "joint position": JOINT_POSITION,
        "Cartesian pose": CARTESIAN_POSITION,
        "Cartesian velocity": CARTESIAN_VELOCITY,
    }
    print(f"{'row':<32}{'us/cycle':>10}{'vs joint':>10}")
    for n in args.arms:
        joint = None
        for name, generator in generators.items():
            cpu = cycle_cpu(motion(n, generator, args.rotate), args.cycles, args.repeats)
            joint = joint or cpu
            print(f"{f'{name}, n={n}':<32}{cpu * 1e6:>10.1f}{cpu / joint:>10.2f}")


if __name__ == "__main__":
    main()
