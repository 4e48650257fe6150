"""franky scenarios, each run in its own process by the socket tests.

`python franky_client.py SCENARIO HOST` prints one JSON line (the scenario's
result) as its last line. libfranka has no reply timeout, so the tests run
these in child processes they can kill; franky and pylibfranka cannot be
imported into one process (their pybind11 types collide).

franky 2.0.0 API used here: `franky.Robot(host, realtime_config=Ignore)`
(Connect, GetRobotModel x3, SetCollisionBehavior), `robot.state` (a
`RobotState`; `O_T_EE` is an `Affine`), `robot.current_joint_state`
(`JointState` with `position` / `velocity`), `robot.move(JointMotion(JointState(q),
relative_dynamics_factor=...))`, `robot.move(JointVelocityMotion(dq, duration=Duration(ms)))`,
`robot.model.gravity(state)` / `.mass(state)`, `robot.recover_from_errors() -> bool`.
Motions run libfranka's `Robot::control` loop in C++ (100 Hz low-pass filter).
"""

from __future__ import annotations

import time

import franky
import numpy as np
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point


def connect(host: str) -> franky.Robot:
    return franky.Robot(host, realtime_config=franky.RealtimeConfig.Ignore)


def attempt(robot: franky.Robot, motion) -> str | None:
    """``robot.move(motion)``; the exception a client sees, as "Type: text", or None."""
    try:
        robot.move(motion)
    except Exception as exc:  # reported to the test
        return f"{type(exc).__name__}: {exc}"
    return None


def affine_matrix(affine) -> list[list[float]]:
    """A franky `Affine` as a row-major 4x4 nested list."""
    return np.asarray(affine.matrix, dtype=float).tolist()


def state_dict(state) -> dict:
    return {
        "q": list(map(float, state.q)),
        "q_d": list(map(float, state.q_d)),
        "dq": list(map(float, state.dq)),
        "O_T_EE": affine_matrix(state.O_T_EE),
        "O_ddP_O": list(map(float, state.O_ddP_O)),
        "robot_mode": state.robot_mode.name,
        "time": state.time.to_sec() if hasattr(state.time, "to_sec") else float(state.time),
        "current_errors": str(state.current_errors),
        "last_motion_errors": str(state.last_motion_errors),
    }


def scenario_connect_state(host: str) -> dict:
    robot = connect(host)
    state = robot.state
    joint_state = robot.current_joint_state
    return {
        "state": state_dict(state),
        "current_joint_position": list(map(float, joint_state.position)),
        "has_errors": bool(robot.has_errors),
        "is_in_control": bool(robot.is_in_control),
    }


def scenario_joint_motion(host: str) -> dict:
    """JointMotion to a target 0.2 rad away on joints 1 and 4, at 0.2 of the dynamics."""
    robot = connect(host)
    q_before = np.asarray(robot.current_joint_state.position, dtype=float)
    target = q_before.copy()
    target[0] += 0.2
    target[3] += 0.2
    error = None
    t0 = time.monotonic()
    try:
        motion = franky.JointMotion(
            franky.JointState(target), relative_dynamics_factor=franky.RelativeDynamicsFactor(0.2)
        )
        robot.move(motion)
    except Exception as exc:  # reported to the test
        error = f"{type(exc).__name__}: {exc}"
    duration = time.monotonic() - t0
    time.sleep(0.2)
    state = robot.state
    return {
        "q_before": q_before.tolist(),
        "target": target.tolist(),
        "q_after": list(map(float, state.q)),
        "robot_mode": state.robot_mode.name,
        "duration": duration,
        "error": error,
    }


def scenario_joint_velocity_motion(host: str) -> dict:
    """JointVelocityMotion: joints 4 and 7 at +/-0.1 rad/s held for 0.5 s, then stopped."""
    robot = connect(host)
    q_before = np.asarray(robot.current_joint_state.position, dtype=float)
    velocity = np.array([0.0, 0.0, 0.0, 0.1, 0.0, 0.0, -0.1])
    hold_ms = 500
    error = None
    t0 = time.monotonic()
    try:
        motion = franky.JointVelocityMotion(
            velocity,
            duration=franky.Duration(hold_ms),
            relative_dynamics_factor=franky.RelativeDynamicsFactor(0.2),
        )
        robot.move(motion)
    except Exception as exc:  # reported to the test
        error = f"{type(exc).__name__}: {exc}"
    duration = time.monotonic() - t0
    time.sleep(0.2)
    state = robot.state
    return {
        "q_before": q_before.tolist(),
        "q_after": list(map(float, state.q)),
        "dq_after": list(map(float, state.dq)),
        "velocity": velocity.tolist(),
        "hold_seconds": hold_ms / 1000,
        "robot_mode": state.robot_mode.name,
        "duration": duration,
        "error": error,
    }


def scenario_model(host: str) -> dict:
    robot = connect(host)
    state = robot.state
    model = robot.model
    return {
        "q": list(map(float, state.q)),
        "gravity": np.asarray(model.gravity(state), dtype=float).tolist(),
        "mass": np.asarray(model.mass(state), dtype=float).tolist(),
    }


def scenario_recover(host: str) -> dict:
    robot = connect(host)
    mode_before = robot.state.robot_mode.name
    t0 = time.monotonic()
    returned = robot.recover_from_errors()
    elapsed = time.monotonic() - t0
    state = robot.state
    return {
        "mode_before": mode_before,
        "returned": bool(returned),
        "elapsed": elapsed,
        "mode_after": state.robot_mode.name,
        "has_errors": bool(robot.has_errors),
    }


def cartesian_move(host: str, motion) -> dict:
    """``robot.move(motion)``; the EE pose before and after, the mode, the error text."""
    robot = connect(host)
    before = affine_matrix(robot.state.O_T_EE)
    error = None
    try:
        robot.move(motion)
    except Exception as exc:  # reported to the test
        error = f"{type(exc).__name__}: {exc}"
    time.sleep(0.2)
    state = robot.state
    return {
        "before": before,
        "after": affine_matrix(state.O_T_EE),
        "robot_mode": state.robot_mode.name,
        "error": error,
    }


def scenario_cartesian_motion(host: str) -> dict:
    """CartesianMotion 5 cm along the EE's own x (a relative target) at 0.2 of the dynamics."""
    target = franky.CartesianState(franky.Affine([0.05, 0.0, 0.0]))
    dynamics = franky.RelativeDynamicsFactor(0.2)
    return cartesian_move(
        host, franky.CartesianMotion(target, franky.ReferenceType.Relative, dynamics)
    )


def scenario_cartesian_velocity_motion(host: str) -> dict:
    """CartesianVelocityMotion: 2 cm/s along base z held for 0.5 s, then stopped."""
    motion = franky.CartesianVelocityMotion(
        franky.RobotVelocity(franky.Twist([0.0, 0.0, 0.02])),
        duration=franky.Duration(500),
        relative_dynamics_factor=franky.RelativeDynamicsFactor(0.2),
    )
    return cartesian_move(host, motion)


if __name__ == "__main__":
    scenario_main.run(globals())
