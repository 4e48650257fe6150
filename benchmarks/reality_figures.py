"""The figures of docs/reality.md: what a robot under a reality profile reads at rest, and
the torque error of libfranka's joint_impedance_control logic through pylibfranka.

    python benchmarks/reality_figures.py [--seeds N] [--no-socket]

1. At rest (in-process, one robot, 1.5 s, the last second read): for ``fr3`` and for
   ``randomized`` seeds 0..N-1, at four poses: |O_F_ext_hat_K|'s force (mean over the
   second), tau_ext_hat_filtered's largest joint, tau_J's largest standard deviation,
   and whether a contact flag rose (libfranka's and the robot's default thresholds).
2. Against ``franka-sim-gym serve --reality P --lockstep`` (ideal, fr3, randomized seed
   1): tests/e2e/clients/reality_client.py's ``rest`` and ``joint_impedance`` scenarios
   (a pylibfranka readOnce loop, and the example's control law with its printed error).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import smoke  # benchmarks/smoke.py: --smoke

from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.reality import DrawBatch, draw, load_profile
from franka_sim_gym.server.testing import start_server
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.world import HOME_Q

ROOT = Path(__file__).resolve().parent.parent
#: Resting poses: home, reaching forward, turned to the side, low over the table.
POSES = {
    "home": HOME_Q,
    "forward": np.array([0.0, 0.3, 0.0, -1.8, 0.0, 2.1, 0.785]),
    "side": np.array([0.8, -0.2, 0.3, -2.2, 0.1, 2.0, 0.3]),
    "low": np.array([0.0, 0.6, 0.0, -1.6, 0.0, 2.6, 0.785]),
}


def at_rest(profile: str, seed: int, q: np.ndarray) -> tuple[float, float, float, bool]:
    """(|F| [N], max |tau_ext| [Nm], max std tau_J [Nm], contact) over the last second of
    1.5 s at rest."""
    ctrl = FciController(ArmPhysics(1))
    ctrl.apply_reality([0], DrawBatch.stack([draw(load_profile(profile), seed)]))
    ctrl.reset([0], q[None])
    F, tau_ext, tau_J, contact = [], [], [], False
    for k in range(1500):
        ctrl.step()
        if k < 500:
            continue
        s = ctrl.states[0]
        F.append(s["O_F_ext_hat_K"][:3].astype(float))
        tau_ext.append(s["tau_ext_hat_filtered"].astype(float))
        tau_J.append(s["tau_J"].astype(float))
        contact |= bool(s["joint_contact"].any() or s["cartesian_contact"].any())
    force = float(np.linalg.norm(np.mean(F, axis=0)))
    ext = float(np.abs(np.mean(tau_ext, axis=0)).max())
    return force, ext, float(np.std(tau_J, axis=0).max()), contact


def rest_table(seeds: int) -> None:
    print("at rest, 1 s:   |F| N  max|tau_ext| Nm  max std tau_J Nm  contact")
    runs = [("fr3", 0)] + [("randomized", s) for s in range(seeds)]
    for profile, seed in runs:
        for pose, q in POSES.items():
            force, ext, std, contact = at_rest(profile, seed, q)
            name = profile if profile == "fr3" else f"{profile} {seed}"
            print(f"{name:<14}{pose:<9}{force:>6.2f}{ext:>13.3f}{std:>18.4f}  {contact}")


def socket_table() -> None:
    client = ROOT / "tests" / "e2e" / "clients" / "reality_client.py"
    print("\nserve --reality P --lockstep; pylibfranka   max std tau_J  |F| N  contact  "
          "joint impedance RMS Nm (max)")  # fmt: skip
    for profile, seed in (("ideal", 0), ("fr3", 1), ("randomized", 1)):
        flags = ("--reality", profile, "--reality-seed", str(seed), "--lockstep", "--no-gripper")
        server = start_server(*flags)
        try:
            out = {}
            for scenario in ("rest", "joint_impedance"):
                run = subprocess.run(
                    [sys.executable, str(client), scenario, server.host],
                    capture_output=True, text=True, timeout=120, cwd=ROOT,
                )  # fmt: skip
                out[scenario] = json.loads(run.stdout.strip().splitlines()[-1])
        finally:
            server.stop()
        rest, imp = out["rest"], out["joint_impedance"]
        print(
            f"{profile + ' ' + str(seed):<42}{max(rest['tau_J_std']):>12.4f}"
            f"{rest['F_norm']:>7.2f}  {rest['contact']!s:<8}{imp['rms']:>12.3f} ({imp['max']:.3f})"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="randomized seeds at rest")
    parser.add_argument("--no-socket", action="store_true", help="skip the served robot")
    args = smoke.parse_args(parser, seeds=1)
    rest_table(args.seeds)
    if not args.no_socket:
        socket_table()


if __name__ == "__main__":
    main()
