"""pylibfranka scenarios for `serve --lockstep`, each run in its own process by the tests
(and by benchmarks/lockstep_rate.py).

`python lockstep_client.py SCENARIO HOST` prints one JSON line (the scenario's result)
as its last line. Every scenario is deterministic in robot time: it takes its time
from ``RobotState::time`` relative to the first state of its loop, never from the
wall clock or from readOnce's period (which, on the first call, counts the states
the mode switch took).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point

#: Every numeric RobotState attribute but ``time`` (absolute robot time depends on how
#: long the server idled before the motion, which runs on the wall clock); the modes
#: and the error lists are added as text (state_values).
FIELDS = tuple(
    name
    for name in dir(fr.RobotState)
    if not name.startswith("_")
    and name not in ("time", "robot_mode", "current_errors", "last_motion_errors")
)


def robot_ms(state) -> int:
    """The state's time in whole milliseconds (its message_id: docs/libfranka-client.md §2);
    pylibfranka hands it over in seconds as a double."""
    return round(state.time.to_sec() * 1000.0)


def connect(host: str) -> fr.Robot:
    return fr.Robot(host, fr.RealtimeConfig.kIgnore)


def state_values(state, t0_ms: int) -> dict:
    """One state's fields by name: every numeric field, the modes, the errors, and the
    time since the loop's first state [ms]."""
    values = {"time_ms": float(robot_ms(state) - t0_ms)}
    for name in FIELDS:
        value = getattr(state, name)
        values[name] = list(map(float, value)) if hasattr(value, "__len__") else float(value)
    values["robot_mode"] = state.robot_mode.name
    values["current_errors"] = str(state.current_errors)
    values["last_motion_errors"] = str(state.last_motion_errors)
    return values


def state_bytes(state, t0_ms: int) -> bytes:
    """One state as bytes, bit for bit (floats as IEEE doubles, not decimal text)."""
    parts = []
    for value in state_values(state, t0_ms).values():
        if isinstance(value, str):
            parts.append(value.encode() + b"|")
        else:
            values = value if isinstance(value, list) else [value]
            parts.append(struct.pack(f"<{len(values)}d", *values))
    return b"".join(parts)


def scenario_motion(host: str) -> dict:
    """A MOTION_SECONDS (default 5) joint-position motion of the shape of libfranka's
    generate_joint_position_motion (joints 4, 5, 7 by 0.2 (1 - cos(2 pi t / T)));
    the wall time it took, the robot time, and a digest of every state it read.

    STALL_MS > 0 stalls the client that long every 50th state, as a loaded machine does.
    """
    duration = float(os.environ.get("MOTION_SECONDS", "5"))
    stall = float(os.environ.get("STALL_MS", "0")) / 1000.0
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    digest = hashlib.sha256()
    q0 = None
    t0_ms = 0
    states = 0
    rates = []
    error = None
    dump = open(os.environ["STATE_DUMP"], "w") if os.environ.get("STATE_DUMP") else None
    wall0 = time.monotonic()
    try:
        while True:
            state, _ = control.readOnce()
            if q0 is None:
                q0, t0_ms = list(state.q_d), robot_ms(state)
            digest.update(state_bytes(state, t0_ms))
            if dump is not None:  # to find where two runs part (STATE_DUMP=path)
                dump.write(json.dumps(state_values(state, t0_ms)) + "\n")
            states += 1
            if stall and states % 50 == 0:
                time.sleep(stall)
            rates.append(state.control_command_success_rate)
            t = (robot_ms(state) - t0_ms) / 1000.0
            delta = 0.2 * (1 - math.cos(2 * math.pi * min(t, duration) / duration))
            q = list(q0)
            for j in (3, 4, 6):
                q[j] += delta
            command = fr.JointPositions(q)
            command.motion_finished = t >= duration
            control.writeOnce(command)
            if t >= duration:
                break
    except fr.ControlException as exc:
        error = str(exc)
    wall = time.monotonic() - wall0
    robot_seconds = (robot_ms(state) - t0_ms) / 1000.0
    del control
    final = robot.read_once()
    return {
        "error": error,
        "wall_seconds": wall,
        "robot_seconds": robot_seconds,
        "states": states,
        "digest": digest.hexdigest(),
        "min_success_rate_after_100": min(rates[100:]),
        "final_mode": final.robot_mode.name,
        "q_final": list(final.q),
    }


def scenario_rate(host: str) -> dict:
    """A readOnce/writeOnce loop holding the start pose for RATE_SECONDS of wall time:
    cycles per wall second (robot time over wall time) and the success rate."""
    seconds = float(os.environ.get("RATE_SECONDS", "5"))
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    state, _ = control.readOnce()
    q0, first_ms = list(state.q_d), robot_ms(state)
    control.writeOnce(fr.JointPositions(q0))
    loops, rates = 0, []
    print("loop-start", flush=True)  # benchmarks/lockstep_rate.py reads the server's CPU here
    wall0 = time.monotonic()
    while True:
        state, _ = control.readOnce()
        loops += 1
        rates.append(state.control_command_success_rate)
        command = fr.JointPositions(q0)
        command.motion_finished = time.monotonic() - wall0 >= seconds
        control.writeOnce(command)
        if command.motion_finished:
            break
    wall = time.monotonic() - wall0
    print("loop-end", flush=True)
    cycles = robot_ms(state) - first_ms
    return {
        "cycles": cycles,
        "loops": loops,
        "wall_seconds": wall,
        "cycles_per_s": cycles / wall,
        "success_rate_mean": sum(rates[200:]) / max(1, len(rates[200:])),
    }


def scenario_go_silent(host: str) -> dict:
    """Answer 100 states, then keep reading without answering: the wall time until the
    robot aborts the motion (the ControlException readOnce raises)."""
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    q0 = None
    for _ in range(100):
        state, _ = control.readOnce()
        q0 = q0 or list(state.q_d)
        control.writeOnce(fr.JointPositions(q0))
    silent_at_ms = robot_ms(state)
    wall0 = time.monotonic()
    error, reads = None, 0
    try:
        while time.monotonic() - wall0 < 30.0:
            state, _ = control.readOnce()
            reads += 1
    except fr.ControlException as exc:
        error = str(exc)
    wall = time.monotonic() - wall0
    del control
    after = robot.read_once()
    return {
        "error": error,
        "wall_seconds": wall,
        "reads": reads,
        "robot_ms_silent": robot_ms(state) - silent_at_ms,
        "mode_after": after.robot_mode.name,
    }


def scenario_skip_states(host: str) -> dict:
    """Answer only every other state for 400 states (a loop too slow in robot time)."""
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    q0, rates, error = None, [], None
    try:
        for k in range(400):
            state, _ = control.readOnce()
            q0 = q0 or list(state.q_d)
            rates.append(state.control_command_success_rate)
            if k % 2 == 0:
                command = fr.JointPositions(q0)
                command.motion_finished = k == 398
                control.writeOnce(command)
                if command.motion_finished:
                    break
    except fr.ControlException as exc:
        error = str(exc)
    del control
    return {
        "error": error,
        "success_rate_last": rates[-2],
        "final_mode": robot.read_once().robot_mode.name,
    }


if __name__ == "__main__":
    scenario_main.run(globals())
