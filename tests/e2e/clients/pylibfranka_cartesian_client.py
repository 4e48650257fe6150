"""pylibfranka's Cartesian control loops: the shapes of its cartesian_pose_example and
cartesian_velocity_example, and a first pose 15 cm off (16).

`python pylibfranka_cartesian_client.py SCENARIO HOST` prints one JSON line
(scenario_main.py).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from pylibfranka_client import connect

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from tests.profiles import positions, there_and_back  # noqa: E402


def stream(control, duration: float, command_at) -> str | None:
    """libfranka's active control loop: readOnce, ``command_at(state, t)``, writeOnce, until
    ``duration`` has passed (the last command finishes the motion). The ControlException
    text, or None."""
    t = 0.0
    try:
        while True:
            state, period = control.readOnce()
            t += period.to_sec()
            command = command_at(state, min(t, duration))
            command.motion_finished = t >= duration
            control.writeOnce(command)
            if t >= duration:
                return None
    except fr.ControlException as exc:
        return str(exc)


def scenario_cartesian_pose(host: str) -> dict:
    """The shape of libfranka's cartesian_pose_example: the EE swings on an arc in the
    x-z plane, angle = pi/4 (1 - cos(pi t / T)), radius 5 cm (ends 5 cm +x, 5 cm -z)."""
    robot = connect(host)
    control = robot.start_cartesian_pose_control(fr.ControllerMode.JointImpedance)
    duration, radius = 2.5, 0.05
    start = []

    def pose_at(state, t: float):
        if not start:
            start.extend(state.O_T_EE_c)
        angle = math.pi / 4 * (1 - math.cos(math.pi * t / duration))
        pose = list(start)
        pose[12] += radius * math.sin(angle)
        pose[14] += radius * (math.cos(angle) - 1)
        return fr.CartesianPose(pose)

    error = stream(control, duration, pose_at)
    del control
    time.sleep(0.3)
    after = robot.read_once()
    return {
        "error": error,
        "pose_start": start,
        "O_T_EE_after": list(after.O_T_EE),
        "robot_mode": after.robot_mode.name,
    }


def scenario_cartesian_velocity(host: str) -> dict:
    """The shape of libfranka's cartesian_velocity_example: v = v_max/2 (1 - cos(2 pi t / T))
    along (cos 45deg, 0, -sin 45deg) for one period: a 5 cm twist integral."""
    robot = connect(host)
    before = list(robot.read_once().O_T_EE)
    control = robot.start_cartesian_velocity_control(fr.ControllerMode.JointImpedance)
    period_s, v_max, angle = 2.0, 0.05, math.pi / 4
    echo = []

    def twist_at(state, t: float):
        echo.append((list(state.O_dP_EE_c), list(state.O_T_EE_d)))
        v = v_max / 2 * (1 - math.cos(2 * math.pi * t / period_s))
        return fr.CartesianVelocities([math.cos(angle) * v, 0, -math.sin(angle) * v, 0, 0, 0])

    error = stream(control, period_s, twist_at)
    del control
    time.sleep(0.3)
    after = robot.read_once()
    mid = echo[len(echo) // 2]
    return {
        "error": error,
        "O_T_EE_before": before,
        "O_T_EE_after": list(after.O_T_EE),
        "O_dP_EE_c_mid": mid[0],
        "O_T_EE_d_mid": mid[1],
        "expected_displacement": v_max / 2 * period_s,
        "robot_mode": after.robot_mode.name,
    }


def scenario_cartesian_start_off(host: str) -> dict:
    """A pose motion whose first pose is 15 cm off the robot's."""
    robot = connect(host)
    control = robot.start_cartesian_pose_control(fr.ControllerMode.JointImpedance)
    error = None
    try:
        for _ in range(100):
            state, _period = control.readOnce()
            pose = list(state.O_T_EE_c)
            pose[12] += 0.15
            control.writeOnce(fr.CartesianPose(pose))
    except fr.ControlException as exc:
        error = str(exc)
    del control
    return {"error": error, "robot_mode": robot.read_once().robot_mode.name}


def scenario_fast_ramp(host: str) -> dict:
    """After 800 states at rest (the external wrench estimate settled): a pose motion
    along +x at 3.5 m/s^2 (jerk 500 m/s^3) to 0.2 m/s and back to rest. Its joint side
    accelerates past the FR3's 10 rad/s^2 (cartesian_motion_generator_joint_velocity_
    discontinuity, tests/fci/cartesian/test_cartesian_rows.py); it passes under
    `serve --joint-discontinuity-scale 2`."""
    robot = connect(host)
    for _ in range(800):
        rest = robot.read_once()
    speeds = there_and_back(0.2, 3.5, 500.0)
    control = robot.start_cartesian_pose_control(fr.ControllerMode.JointImpedance)
    start: list[float] = []
    x = positions(speeds)

    def pose_at(state, t: float):
        if not start:
            start.extend(state.O_T_EE_c)
        pose = list(start)
        pose[12] += x[min(round(t * 1e3), len(x) - 1)]
        return fr.CartesianPose(pose)

    error = stream(control, len(speeds) * 1e-3, pose_at)
    del control
    after = robot.read_once()
    return {
        "O_F_ext_hat_K_at_rest": list(rest.O_F_ext_hat_K),
        "error": error,
        "moved": after.O_T_EE[12] - start[12] if start else None,
        "distance": x[-1],
        "robot_mode": after.robot_mode.name,
    }


if __name__ == "__main__":
    scenario_main.run(globals())
