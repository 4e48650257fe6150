"""pylibfranka scenarios, each run in its own process by the socket tests.

`python pylibfranka_client.py SCENARIO HOST` prints one JSON line (the
scenario's result) as its last line. libfranka has no reply timeout, so the
tests run these in child processes they can kill; pylibfranka and franky
cannot be imported into one process (their pybind11 types collide). The reflex and
Cartesian scenarios have their own scripts (pylibfranka_reflex_client.py,
pylibfranka_cartesian_client.py), which share ``connect`` and the motions here.
"""

from __future__ import annotations

import json
import math
import os
import threading
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point

HOME = [0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]


def connect(host: str) -> fr.Robot:
    return fr.Robot(host, fr.RealtimeConfig.kIgnore)


def state_dict(state) -> dict:
    names = (
        "q",
        "q_d",
        "dq",
        "dq_d",
        "ddq_d",
        "tau_J",
        "tau_J_d",
        "O_T_EE",
        "O_T_EE_d",
        "O_T_EE_c",
        "F_T_EE",
        "F_T_NE",
        "NE_T_EE",
        "elbow",
        "O_ddP_O",
        "theta",
        "dtheta",
    )
    out = {name: list(getattr(state, name)) for name in names}
    out["time"] = state.time.to_sec()
    out["robot_mode"] = state.robot_mode.name
    out["success_rate"] = state.control_command_success_rate
    out["current_errors"] = str(state.current_errors)
    out["last_motion_errors"] = str(state.last_motion_errors)
    return out


def cosine_motion(robot: fr.Robot, duration: float = 3.0, amplitude: float = math.pi / 8) -> dict:
    """The shape of libfranka's generate_joint_position_motion: joints 4, 5, 7 move by
    amplitude * (1 - cos(2 pi t / duration)), starting and ending at rest."""
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    t = 0.0
    q0 = None
    max_err = 0.0
    rates = []
    cycles = 0
    while True:
        state, period = control.readOnce()
        t += period.to_sec()
        if q0 is None:
            q0 = list(state.q_d)
        else:
            max_err = max(max_err, max(abs(a - b) for a, b in zip(state.q, state.q_d, strict=True)))
        rates.append(state.control_command_success_rate)
        delta = amplitude * (1 - math.cos(2 * math.pi * t / duration))
        q = list(q0)
        for j in (3, 4, 6):
            q[j] += delta
        command = fr.JointPositions(q)
        cycles += 1
        if t >= duration:
            command.motion_finished = True
            control.writeOnce(command)
            break
        control.writeOnce(command)
    final = robot.read_once()
    return {
        "cycles": cycles,
        "max_tracking_error": max_err,
        "q_start": q0,
        "final": state_dict(final),
        "min_success_rate_after_1s": min(rates[1000:]) if len(rates) > 1000 else None,
    }


def scenario_read_once(host: str) -> dict:
    robot = connect(host)
    first = state_dict(robot.read_once())
    second = state_dict(robot.read_once())
    return {"first": first, "second": second}


def scenario_load_model(host: str) -> dict:
    robot = connect(host)
    model = robot.load_model()
    state = robot.read_once()
    return {
        "q": list(state.q),
        "gravity": list(model.gravity(state)),
        "mass": list(model.mass(state)),
        "zero_jacobian": list(model.zero_jacobian(state)),
        "O_ddP_O": list(state.O_ddP_O),
        "tau_J": list(state.tau_J),
        "m_ee": state.m_ee,
    }


def scenario_cosine_motion(host: str) -> dict:
    return cosine_motion(connect(host))


def scenario_joint_velocity(host: str) -> dict:
    """Joint 4 and 7 at a smooth velocity bump for 2 s, starting and ending at rest."""
    robot = connect(host)
    q_before = list(robot.read_once().q)
    control = robot.start_joint_velocity_control(fr.ControllerMode.JointImpedance)
    t = 0.0
    duration = 2.0
    peak = 0.3
    max_dq_err = 0.0
    while True:
        state, period = control.readOnce()
        t += period.to_sec()
        v = peak * math.sin(math.pi * min(t, duration) / duration) ** 2
        errors = (abs(a - b) for a, b in zip(state.dq, state.dq_d, strict=True))
        max_dq_err = max(max_dq_err, max(errors))
        dq = [0.0, 0.0, 0.0, v, 0.0, 0.0, -v]
        command = fr.JointVelocities(dq)
        if t >= duration:
            command.motion_finished = True
            control.writeOnce(command)
            break
        control.writeOnce(command)
    time.sleep(0.2)
    after = robot.read_once()
    return {
        "q_before": q_before,
        "q_after": list(after.q),
        "max_velocity_tracking_error": max_dq_err,
        "robot_mode": after.robot_mode.name,
        "expected_displacement": peak * duration / 2,
    }


def scenario_torque_zero_hold(host: str) -> dict:
    robot = connect(host)
    control = robot.start_torque_control()
    t = 0.0
    q0 = None
    max_dev = 0.0
    tau_J = None
    while True:
        state, period = control.readOnce()
        t += period.to_sec()
        if q0 is None:
            q0 = list(state.q)
        max_dev = max(max_dev, max(abs(a - b) for a, b in zip(state.q, q0, strict=True)))
        tau_J = list(state.tau_J)
        command = fr.Torques([0.0] * 7)
        if t >= 2.0:
            command.motion_finished = True
            control.writeOnce(command)
            break
        control.writeOnce(command)
    final = robot.read_once()
    return {
        "max_deviation": max_dev,
        "tau_J": tau_J,
        "final_mode": final.robot_mode.name,
        "q_d_frozen": list(final.q_d),
    }


def scenario_stop_from_thread(host: str) -> dict:
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    stopper_error = []

    def stopper() -> None:
        time.sleep(0.5)
        try:
            robot.stop()
        except Exception as exc:  # reported, not raised, in the thread
            stopper_error.append(repr(exc))

    thread = threading.Thread(target=stopper)
    thread.start()
    error = None
    q0 = None
    t0 = time.monotonic()
    try:
        while time.monotonic() - t0 < 5.0:
            state, _ = control.readOnce()
            if q0 is None:
                q0 = list(state.q_d)
            control.writeOnce(fr.JointPositions(q0))
    except fr.ControlException as exc:
        error = str(exc)
    thread.join()
    del control
    final = robot.read_once()
    return {"error": error, "stopper_error": stopper_error, "mode": final.robot_mode.name}


def scenario_vanish_mid_motion(host: str) -> dict:
    """Start a motion, then die without a word (no StopMove, no FIN handshake of libfranka)."""
    robot = connect(host)
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    state, _ = control.readOnce()
    q0 = list(state.q_d)
    for _ in range(200):
        state, _ = control.readOnce()
        control.writeOnce(fr.JointPositions(q0))
    print(json.dumps({"vanished_after_cycles": 200}), flush=True)
    os._exit(0)


def scenario_reconnect_and_move(host: str) -> dict:
    robot = connect(host)
    state = robot.read_once()
    result = cosine_motion(robot, duration=1.0, amplitude=0.05)
    result["mode_on_connect"] = state.robot_mode.name
    return result


def scenario_hold_connection(host: str) -> dict:
    """Connect and keep reading states until told on stdin, then 100 more (the 'first
    client' of a second-client test; scenario_main.hold_until_told)."""
    robot = connect(host)
    return scenario_main.hold_until_told(
        lambda: round(robot.read_once().time.to_sec() * 1000), more=100
    )


def scenario_connect_only(host: str) -> dict:
    try:
        connect(host)
    except Exception as exc:
        return {"error_type": type(exc).__name__, "error": str(exc)}
    return {"error": None}


def scenario_reconnect_loop(host: str) -> dict:
    """RECONNECTS times: a new Robot (Connect, a state, GetRobotModel), one read_once,
    then the Robot is dropped and the next one made at once (a test loop's pattern)."""
    refused = []
    for k in range(int(os.environ.get("RECONNECTS", "100"))):
        try:
            robot = connect(host)
            robot.read_once()
            del robot  # closes the connection
        except Exception as exc:
            refused.append(f"{k}: {type(exc).__name__}: {exc}")
    return {"refused": refused}


def scenario_rate(host: str) -> dict:
    """States/s received by read_once over N s, then a readOnce/writeOnce loop's success rate."""
    seconds = float(os.environ.get("RATE_SECONDS", "10"))
    robot = connect(host)
    first = robot.read_once()
    t0 = time.monotonic()
    last = first
    reads = 0
    while time.monotonic() - t0 < seconds:
        last = robot.read_once()  # blocks until a newer state than the last one
        reads += 1
    elapsed = time.monotonic() - t0
    # message ids count milliseconds: the states published over the interval
    published_per_s = (last.time.to_sec() - first.time.to_sec()) * 1000.0 / elapsed
    states_per_s = reads / elapsed
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    q0 = None
    rates = []
    t1 = time.monotonic()
    while True:
        state, _ = control.readOnce()
        if q0 is None:
            q0 = list(state.q_d)
        rates.append(state.control_command_success_rate)
        command = fr.JointPositions(q0)
        if time.monotonic() - t1 > seconds:
            command.motion_finished = True
            control.writeOnce(command)
            break
        control.writeOnce(command)
    # The rate's 100-cycle window is full after 200 cycles; a short loop on a loaded
    # machine (socket_rate.py --smoke) may not get there: then every cycle counts.
    window = rates[200:] or rates
    return {
        "states_per_s": states_per_s,
        "published_per_s": published_per_s,
        "loop_success_rate_mean": sum(window) / len(window),
        "loop_success_rate_min": min(window),
    }


def move_to(robot: fr.Robot, target: list[float], duration: float) -> None:
    """A smooth (cosine-blended) joint-position motion to ``target``."""
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    t, q0 = 0.0, None
    while True:
        state, period = control.readOnce()
        t += period.to_sec()
        if q0 is None:
            q0 = list(state.q_d)
        s = 0.5 * (1 - math.cos(math.pi * min(t / duration, 1.0)))
        command = fr.JointPositions([a + s * (b - a) for a, b in zip(q0, target, strict=True)])
        if t >= duration:
            command.motion_finished = True
            control.writeOnce(command)
            return
        control.writeOnce(command)


if __name__ == "__main__":
    scenario_main.run(globals())
