"""pylibfranka scenarios that end in a reflex: each provocation (a start pose off, a
1 rad step, a 50 rad/s dq_c step, a torque step, the self-collision fold) and a loop that
goes silent (lost cycles); then the refused Move, the recovery and the next motion.

`python pylibfranka_reflex_client.py SCENARIO HOST` prints one JSON line (scenario_main.py).
"""

from __future__ import annotations

import math
import os
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from pylibfranka_client import connect, cosine_motion, move_to, read_after_recovery, state_dict

#: Start pose of the fold: shoulder forward (q2 = 0.3), so that folding joint 4 brings
#: the wrist down onto the base within 50 mm before joint 4 reaches its stop.
FOLD_START = [0.0, 0.3, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]


def _provoke(robot: fr.Robot, kind: str) -> str | None:
    """Run one reflex provocation; the ControlException text it ends with (None if none)."""
    if kind == "fold":
        move_to(robot, FOLD_START, 3.0)
    if kind == "torque_step":
        control = robot.start_torque_control()
    elif kind in ("velocity_step", "fold"):
        control = robot.start_joint_velocity_control(fr.ControllerMode.JointImpedance)
    else:
        control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    q0 = None
    t = 0.0
    # An enforcing robot ends the loop with its reflex; one that only logs runs it to the
    # end (CYCLES: a test of that needs only the step and some cycles after it).
    cycles = int(os.environ.get("CYCLES", "20000"))
    try:
        for k in range(cycles):
            state, period = control.readOnce()
            t += period.to_sec()
            if q0 is None:
                q0 = list(state.q_d)
            if kind == "start_pose":  # first waypoint +0.2 rad on joint 1
                q = list(q0)
                q[0] += 0.2
                control.writeOnce(fr.JointPositions(q))
            elif kind == "position_step":  # hold, then a 1 rad step on joint 1
                q = list(q0)
                if k >= 50:
                    q[0] += 1.0
                control.writeOnce(fr.JointPositions(q))
            elif kind == "velocity_step":  # rest, then a 50 rad/s step in dq_c
                dq = [0.0] * 7
                if k >= 50:
                    dq[3] = 50.0
                control.writeOnce(fr.JointVelocities(dq))
            elif kind == "torque_step":  # zero torque, then a 5 Nm step on joint 1
                tau = [0.0] * 7
                if k >= 50:
                    tau[0] = 5.0
                control.writeOnce(fr.Torques(tau))
            elif kind == "fold":
                # docs/fci-behaviour.md "self_collision_avoidance_violation (2)": joint 4 folds at
                # -0.1 rad/s while joint 5 turns at 0.2 rad/s (smooth 0.5 s ramps keep the command
                # inside the jerk limit).
                ramp = min(1.0, t / 0.5)
                ramp = ramp * ramp * (3 - 2 * ramp)
                dq = [0.0, 0.0, 0.0, -0.1 * ramp, 0.2 * ramp, 0.0, 0.0]
                control.writeOnce(fr.JointVelocities(dq))
    except fr.ControlException as exc:
        return str(exc)
    finally:
        del control
    return None


def scenario_reflex(host: str) -> dict:
    """A provocation (REFLEX env), then: Move refused, recovery, a fresh motion succeeds."""
    kind = os.environ["REFLEX"]
    robot = connect(host)
    error = _provoke(robot, kind)
    after = robot.read_once()
    refused = None
    try:
        control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
        del control
    except Exception as exc:  # expected: the robot is in Reflex
        refused = f"{type(exc).__name__}: {exc}"
    t0 = time.monotonic()
    robot.automatic_error_recovery()
    recovery_s = time.monotonic() - t0
    recovered = read_after_recovery(robot)
    try:
        motion = cosine_motion(robot, duration=0.5, amplitude=0.02)
        next_error = None
    except fr.ControlException as exc:
        motion, next_error = None, str(exc)
    final = motion["final"] if motion else state_dict(robot.read_once())
    return {
        "error": error,
        "mode_after": after.robot_mode.name,
        "current_errors_after": str(after.current_errors),
        "last_motion_errors_after": str(after.last_motion_errors),
        "q4_after": after.q[3],
        "refused": refused,
        "recovery_s": recovery_s,
        "mode_recovered": recovered.robot_mode.name,
        "current_errors_recovered": str(recovered.current_errors),
        "last_motion_errors_recovered": str(recovered.last_motion_errors),
        "next_motion_error": next_error,
        "next_motion_final_mode": final["robot_mode"],
        "next_motion_last_motion_errors": final["last_motion_errors"],
    }


def scenario_silence(host: str) -> dict:
    """A joint motion whose loop goes silent once, then recovery and a motion: for
    SILENCE_MS of wall time (neither reading nor writing), or for SILENCE_CYCLES of the
    robot's (states read, by their message ids, and not answered)."""
    silence = float(os.environ.get("SILENCE_MS", "0")) / 1000.0
    silent_cycles = int(os.environ.get("SILENCE_CYCLES", "0"))
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    t, q0, error, slept = 0.0, None, None, False
    try:
        while t < 1.5:
            state, period = control.readOnce()
            t += period.to_sec()
            if q0 is None:
                q0 = list(state.q_d)
            if t >= 0.5 and not slept:
                slept = True
                if silent_cycles:  # states read, none answered, until the robot ran them
                    start = state.time.to_sec()
                    while (state.time.to_sec() - start) * 1000.0 < silent_cycles:
                        state, period = control.readOnce()
                        t += period.to_sec()
                else:
                    time.sleep(silence)  # neither reading nor writing: cycles go unanswered
                continue
            q = list(q0)
            q[3] += 0.05 * (1 - math.cos(2 * math.pi * t / 1.5))
            command = fr.JointPositions(q)
            if t >= 1.5:
                command.motion_finished = True
            control.writeOnce(command)
    except fr.ControlException as exc:
        error = str(exc)
    del control
    after = robot.read_once()
    if error is not None:
        robot.automatic_error_recovery()
    motion = cosine_motion(robot, duration=0.5, amplitude=0.02)
    return {
        "error": error,
        "mode_after": after.robot_mode.name,
        "next_motion_final_mode": motion["final"]["robot_mode"],
    }


if __name__ == "__main__":
    scenario_main.run(globals())
