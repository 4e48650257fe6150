"""How much faster than real time a pylibfranka loop runs against `serve --lockstep`.

    python benchmarks/lockstep_rate.py [--seconds S]

Starts `franka-sim-gym serve --no-gripper` twice, on the robot's 1 kHz clock and with
--lockstep, and runs the same pylibfranka readOnce/writeOnce joint-position loop
(tests/e2e/clients/lockstep_client.py, scenario ``rate``: the start pose held) for S
seconds of wall time against each. Prints, per server, the robot cycles per second
of wall time (the robot's time over the wall time), its ratio to real time
(1000 cycles/s), the loop's success rate and the server's own CPU time per cycle
(user + system of the server process over the cycles it ran, from /proc), and the
ratio of the two rates.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import smoke  # benchmarks/smoke.py: --smoke

from franka_sim_gym.server.testing import start_server

ROOT = Path(__file__).resolve().parent.parent
CLIENT = ROOT / "tests" / "e2e" / "clients" / "lockstep_client.py"


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(seconds: float, *flags: str) -> dict:
    """One server with ``flags``, one ``rate`` loop of ``seconds`` against it."""
    server = start_server("--no-gripper", "--log-level", "WARNING", *flags)
    try:
        client = subprocess.Popen(
            [sys.executable, str(CLIENT), "rate", server.host],
            stdout=subprocess.PIPE,
            text=True,
            env={**os.environ, "RATE_SECONDS": str(seconds)},
        )
        assert client.stdout is not None
        cpu = {}
        for line in client.stdout:  # the client marks its loop's start and end
            if line.startswith("loop-"):
                cpu[line.strip()] = cpu_seconds(server.process.pid)
            elif line.startswith("{"):
                result = json.loads(line)
        client.wait(timeout=60)
    finally:
        server.stop()
    if "cycles" not in result:
        raise SystemExit(f"the client failed: {result}")
    spent = cpu["loop-end"] - cpu["loop-start"]
    result["server_cpu_us_per_cycle"] = spent / result["cycles"] * 1e6
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="wall time of each loop")
    args = smoke.parse_args(parser, seconds=0.5)
    real_time = measure(args.seconds)
    lockstep = measure(args.seconds, "--lockstep")
    print(
        f"{'server':<22}{'cycles/s (wall)':>16}{'x real time':>13}{'success rate':>14}"
        f"{'server CPU/cycle':>18}"
    )
    for name, r in (("1 kHz (default)", real_time), ("--lockstep", lockstep)):
        print(
            f"{name:<22}{r['cycles_per_s']:>16.0f}{r['cycles_per_s'] / 1000:>12.2f}x"
            f"{r['success_rate_mean']:>14.3f}{r['server_cpu_us_per_cycle']:>15.1f} us"
        )
    ratio = lockstep["cycles_per_s"] / real_time["cycles_per_s"]
    print(f"lockstep / 1 kHz: {ratio:.2f}x")
    print(
        f"summary: realtime_cycles_per_s={real_time['cycles_per_s']:.0f} "
        f"lockstep_cycles_per_s={lockstep['cycles_per_s']:.0f} ratio={ratio:.2f} "
        f"lockstep_server_cpu_us_per_cycle={lockstep['server_cpu_us_per_cycle']:.1f}"
    )


if __name__ == "__main__":
    main()
