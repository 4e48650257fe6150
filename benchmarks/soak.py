"""A soak of socket mode: a real pylibfranka client cycling for N minutes.

    python benchmarks/soak.py [--minutes N] [--server-args "..."]

Starts `franka-sim-gym serve --enforce-motion-limits` on a free loopback address,
then one pylibfranka client process that repeats, as fast as it can:

1. connect (a new ``Robot``: Connect, a state, GetRobotModel);
2. read states with ``read_once`` for 0.3 s (states/s; the robot must be Idle);
3. a 0.5 s joint-position motion that must end with success;
4. a 1 rad position step that the robot must abort with a reflex (ControlException);
5. ``automatic_error_recovery`` and the stream back in Idle;
6. disconnect (the ``Robot`` dropped) and at once the next cycle.

Prints the cycles, their success rate (every step as expected), refused connections,
states/s, and the server's RSS and open file descriptors at the start and the end
(from /proc). A cycle that hangs (libfranka has no reply timeout) is killed after
60 s and counted.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import smoke  # benchmarks/smoke.py: --smoke

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from franka_sim_gym.server.testing import start_server  # noqa: E402

HANG_S = 60.0


# -- the client (a child process: pylibfranka blocks without a timeout) -------------------------


def client_cycle(fr, host: str) -> dict:
    """One connect / read / motion / reflex / recovery / disconnect cycle."""
    try:
        robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    except Exception as exc:  # a refused connection is what the soak counts
        return {"refused": True, "error": f"{type(exc).__name__}: {exc}"}
    steps: dict[str, object] = {"refused": False}
    try:
        t0, reads = time.perf_counter(), 0
        while time.perf_counter() - t0 < 0.3:
            state = robot.read_once()
            reads += 1
        steps["states_per_s"] = reads / (time.perf_counter() - t0)
        steps["idle_on_connect"] = state.robot_mode == fr.RobotMode.Idle
        if state.robot_mode == fr.RobotMode.Reflex:  # a failed cycle before: do not cascade
            recover(fr, robot)
        steps["motion"] = run_motion(fr, robot, step=False)
        steps["reflex"] = run_motion(fr, robot, step=True)
        steps["recovered"] = recover(fr, robot)
    except Exception as exc:
        steps["error"] = f"{type(exc).__name__}: {exc}"
    del robot
    steps["ok"] = (
        "error" not in steps
        and steps["idle_on_connect"]
        and steps["motion"] is None
        and "reflex" in str(steps["reflex"]).lower()
        and steps["recovered"]
    )
    return steps


def recover(fr, robot) -> bool:
    """AutomaticErrorRecovery; True once the stream shows the robot Idle."""
    robot.automatic_error_recovery()
    for _ in range(3000):  # states queued during the deferred reply are stale
        if robot.read_once().robot_mode == fr.RobotMode.Idle:
            return True
    return False


def run_motion(fr, robot, step: bool) -> str | None:
    """0.5 s of joint 4 out by 0.05 rad and back (sin^4: smooth to the jerk; step=False),
    or a hold then a 1 rad step on joint 1 (step=True); None if it ended normally, else
    the exception text."""
    q0, t, k = None, 0.0, 0
    try:
        control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
        while True:
            state, period = control.readOnce()
            t += period.to_sec()
            q0 = q0 or list(state.q_d)
            q = list(q0)
            if step:
                q[0] += 1.0 if k >= 50 else 0.0
            else:
                q[3] += 0.05 * math.sin(math.pi * min(t, 0.5) / 0.5) ** 4
            command = fr.JointPositions(q)
            command.motion_finished = not step and t >= 0.5
            control.writeOnce(command)
            k += 1
            if command.motion_finished or k > 5000:
                break
        while robot.read_once().robot_mode != fr.RobotMode.Idle:
            pass
        return None
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"


def run_client(host: str, seconds: float) -> None:
    import pylibfranka as fr

    end = time.monotonic() + seconds
    while time.monotonic() < end:
        print(json.dumps(client_cycle(fr, host)), flush=True)


# -- the soak ------------------------------------------------------------------------------------


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def open_fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--server-args", default="", help="extra serve flags")
    parser.add_argument("--client", metavar="HOST", help=argparse.SUPPRESS)
    args = smoke.parse_args(parser, minutes=0.05)
    if args.client:
        run_client(args.client, args.minutes * 60)
        return
    server = start_server("--enforce-motion-limits", *args.server_args.split(), cwd=ROOT)
    pid = server.process.pid
    start_rss, start_fds = rss_mb(pid), open_fds(pid)
    cycles: list[dict] = []
    hangs = crashes = 0
    deadline = time.monotonic() + args.minutes * 60
    try:
        while time.monotonic() < deadline:
            remaining = deadline - time.monotonic()
            child = subprocess.Popen(
                [
                    sys.executable,
                    __file__,
                    "--client",
                    server.host,
                    "--minutes",
                    str(remaining / 60),
                ],
                stdout=subprocess.PIPE,
                text=True,
            )
            try:
                out, _ = child.communicate(timeout=remaining + HANG_S)
            except subprocess.TimeoutExpired:
                child.kill()
                out, _ = child.communicate()
                hangs += 1
            else:
                crashes += child.returncode != 0
            cycles += [json.loads(line) for line in out.splitlines() if line.startswith("{")]
        end_rss, end_fds = rss_mb(pid), open_fds(pid)
        alive = server.alive()
    finally:
        server.stop()
    # The server's account of every motion: a reflex in a motion that lost cycles is a
    # client the host starved (it resumed with a jump), not a fault of the server.
    ended = re.findall(r"motion ended: (\w+) after \d+ cycles; lost (\d+)", server.log())
    starved = sum(1 for status, lost in ended if status == "kReflexAborted" and int(lost))
    served = [c for c in cycles if not c["refused"]]
    ok = sum(1 for c in served if c.get("ok"))
    rates = [c["states_per_s"] for c in served if "states_per_s" in c]
    rows = [
        ("minutes", f"{args.minutes:g}"),
        ("cycles (connect/read/motion/reflex/recovery/disconnect)", f"{len(cycles)}"),
        ("success rate (every step as expected)", f"{ok / max(1, len(cycles)):.4f}"),
        ("refused connections", f"{len(cycles) - len(served)}"),
        ("hung clients killed / client processes crashed", f"{hangs} / {crashes}"),
        ("reflexes in motions that lost cycles (client starved)", f"{starved}"),
        ("states/s by read_once (mean)", f"{statistics.fmean(rates) if rates else 0:.1f}"),
        ("states/s by read_once (min)", f"{min(rates) if rates else 0:.1f}"),
        ("server RSS at start / end [MB]", f"{start_rss:.1f} / {end_rss:.1f}"),
        ("server open fds at start / end", f"{start_fds} / {end_fds}"),
        ("server alive at the end", f"{alive}"),
    ]
    print(f"{'quantity':<58}{'value':>20}")
    for name, value in rows:
        print(f"{name:<58}{value:>20}")
    failures = [c for c in served if not c.get("ok")][:3]
    for c in failures:
        print("a failed cycle:", json.dumps(c))


if __name__ == "__main__":
    main()
