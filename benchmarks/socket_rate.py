"""What a real pylibfranka client gets from `franka-sim-gym serve` over loopback.

    python benchmarks/socket_rate.py [--seconds S]

Starts the server on a loopback address, then a pylibfranka client that
(1) reads states with read_once for S seconds and (2) runs a readOnce/writeOnce
joint-position loop for S seconds. Reports states/s received, the loop's
control_command_success_rate, and the server process's CPU share of one core
(from /proc, user + system time over wall time) in each phase.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import smoke  # benchmarks/smoke.py: --smoke

from franka_sim_gym.server.testing import start_server

ROOT = Path(__file__).resolve().parent.parent
CLIENT = ROOT / "tests" / "e2e" / "clients" / "pylibfranka_client.py"


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def sleep_share(ticks: int = 2000) -> float:
    """CPU share of one core that pacing a 1 kHz loop with ``time.sleep`` costs on this
    host, with nothing else in the loop: the floor under the server's own share (its
    tick thread sleeps once per cycle; on a VM, arming and taking the timer is not free)."""
    cpu0, start = time.process_time(), time.perf_counter()
    next_t = start
    for _ in range(ticks):
        next_t += 1e-3
        delay = next_t - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    return (time.process_time() - cpu0) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--server-args", default="", help='extra serve flags, e.g. "--no-gripper"')
    args = smoke.parse_args(parser, seconds=0.5)
    # A free loopback address, ready once Connect is answered and a state arrives.
    server = start_server("--log-level", "WARNING", *args.server_args.split(), cwd=ROOT)
    host, pid = server.host, server.process.pid
    try:
        time.sleep(min(0.5, args.seconds))
        idle_cpu0, idle_t0 = cpu_seconds(pid), time.monotonic()
        time.sleep(min(2.0, args.seconds))
        idle_share = (cpu_seconds(pid) - idle_cpu0) / (time.monotonic() - idle_t0)
        cpu0, t0 = cpu_seconds(pid), time.monotonic()
        out = subprocess.run(
            [sys.executable, str(CLIENT), "rate", host],
            capture_output=True,
            text=True,
            timeout=4 * args.seconds + 60,
            env={**os.environ, "RATE_SECONDS": str(args.seconds)},
        ).stdout
        share = (cpu_seconds(pid) - cpu0) / (time.monotonic() - t0)
        result = json.loads(out.strip().splitlines()[-1])
    finally:
        server.stop()
    sleeping = sleep_share(min(2000, int(1000 * args.seconds)))
    rows = [
        ("states/s received by pylibfranka read_once", f"{result['states_per_s']:.1f}", "1000"),
        ("states/s published (message ids over wall time)", f"{result['published_per_s']:.1f}", ""),
        ("server CPU share of one core, no client", f"{idle_share:.1%}", ""),
        ("server CPU share of one core, client reading + 1 kHz loop", f"{share:.1%}", "<= 10%"),
        (
            "of which any 1 kHz sleep loop costs here (measured alone)",
            f"{sleeping:.1%}",
            "",
        ),
        (
            "readOnce/writeOnce loop success rate (mean)",
            f"{result['loop_success_rate_mean']:.3f}",
            "",
        ),
        (
            "readOnce/writeOnce loop success rate (min)",
            f"{result['loop_success_rate_min']:.3f}",
            "",
        ),
    ]
    print(f"{'quantity':<60}{'value':>10}{'target':>10}")
    for name, value, target in rows:
        print(f"{name:<60}{value:>10}{target:>10}")
    print(
        f"summary: states_per_s={result['states_per_s']:.1f} server_cpu_share={share:.3f} "
        f"loop_success_rate={result['loop_success_rate_mean']:.3f}"
    )


if __name__ == "__main__":
    main()
