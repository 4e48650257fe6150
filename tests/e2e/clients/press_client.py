"""pylibfranka: a press on the table, then the switch to the next motion (issue 36).

`python press_client.py SCENARIO HOST` prints one JSON line (scenario_main.py). The
press is the sequence of the issue: SetCollisionBehavior 100 Nm / 100 N,
SetCartesianImpedance([500] * 3 + [150] * 3), then a kCartesianPose motion under the
servo SERVO (env: "cartesian" or "joint") whose pose goes below the table and holds
there; then the robot idles and a next motion starts (a joint-position motion under
JointImpedance back up, or a torque loop commanding zero).
"""

from __future__ import annotations

import math
import os
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from pylibfranka_client import connect, move_to

#: The flange pointing down 18 cm above the table (tests/sim/test_scene.py OVER_THE_TABLE).
OVER_THE_TABLE = [0.0, 0.6, 0.0, -1.9, 0.0, 2.5, math.pi / 4]
#: How far under the table the press commands the flange [m], per servo: the Cartesian
#: servo at 500 N/m presses 10 N there; the joint servo's stiffness at the flange is
#: ~10 kN/m, so 2 mm presses ~20 N (2 cm would be ~200 N, over the 100 N thresholds).
DEPTH = {"cartesian": 0.02, "joint": 0.002}
SERVO = {
    "cartesian": fr.ControllerMode.CartesianImpedance,
    "joint": fr.ControllerMode.JointImpedance,
}
#: The press's timing [s]: down in DESCENT (a cosine ramp), then held until HOLD.
DESCENT, HOLD = 1.5, 3.0
#: Idle between the press and the next motion [s of read_once at ~100 Hz].
IDLE = 0.3


def sample(state) -> dict:
    """What the switch is judged on, from one state."""
    return {
        "F": list(state.O_F_ext_hat_K),
        "tau_ext": list(state.tau_ext_hat_filtered),
        "tau_J": list(state.tau_J),
        "q": list(state.q),
        "z": state.O_T_EE[14],
        "mode": state.robot_mode.name,
    }


def run(control, command_at, until: float) -> tuple[list, str | None]:
    """A readOnce / writeOnce loop: ``command_at(state, t)`` is the command answering the
    state at time t; the motion finishes at ``until`` [s]. Every state read, and the
    ControlException's text (None when the motion finished)."""
    t, states = 0.0, []
    try:
        while True:
            state, period = control.readOnce()
            t += period.to_sec()
            states.append(state)
            command = command_at(state, t)
            command.motion_finished = t >= until
            control.writeOnce(command)
            if command.motion_finished:
                return states, None
    except fr.ControlException as exc:
        return states, str(exc)


def press(robot: fr.Robot, servo: str) -> dict:
    """Move over the table, configure, press DEPTH[servo] under it and hold; the motion's
    last state and its error (None when it finished)."""
    move_to(robot, OVER_THE_TABLE, 1.5)
    robot.set_collision_behavior([100.0] * 7, [100.0] * 7, [100.0] * 6, [100.0] * 6)
    robot.set_cartesian_impedance([500.0] * 3 + [150.0] * 3)
    start: list[float] = []

    def pose_at(state, t: float):
        if not start:
            start.extend(state.O_T_EE_c)
        pose = list(start)
        drop = start[14] + DEPTH[servo]  # to DEPTH under the table's plane z = 0
        pose[14] -= drop * 0.5 * (1 - math.cos(math.pi * min(t / DESCENT, 1.0)))
        return fr.CartesianPose(pose)

    states, error = run(robot.start_cartesian_pose_control(SERVO[servo]), pose_at, HOLD)
    return {"press_error": error, "press": sample(states[-1])}


def idle(robot: fr.Robot) -> list[dict]:
    """read_once for IDLE seconds of the robot's clock (its states' time): the idle hold
    after the press, a sample about every 10 ms."""
    samples = []
    state = robot.read_once()
    start = state.time.to_sec()
    while state.time.to_sec() - start < IDLE:
        samples.append(sample(state))
        time.sleep(0.01)
        state = robot.read_once()
    return samples


def scenario_press_then_move(host: str) -> dict:
    """The press, the idle hold, then a joint-position motion under JointImpedance that
    lifts the flange (joint 2 back by 0.1 rad in 1 s, from the measured q, as libfranka's
    examples start); the first states of that motion and how it ended."""
    robot = connect(host)
    result = press(robot, os.environ.get("SERVO", "cartesian"))
    result["idle"] = idle(robot)
    q0: list[float] = []

    def lift(state, t: float):
        if not q0:
            q0.extend(state.q)
        q = list(q0)
        q[1] -= 0.1 * 0.5 * (1 - math.cos(math.pi * min(t, 1.0)))
        return fr.JointPositions(q)

    try:  # (a reflex at the motion's first cycle already raises from the start)
        states, error = run(robot.start_joint_position_control(SERVO["joint"]), lift, 1.0)
    except fr.ControlException as exc:
        states, error = [], str(exc)
    time.sleep(0.05)
    after = robot.read_once()
    result.update(
        first=[sample(s) for s in states[:3]],
        error=error,
        after=sample(after),
        last_motion_errors=str(after.last_motion_errors),
    )
    return result


def scenario_press_then_torque(host: str) -> dict:
    """The press, the idle hold, then a torque loop commanding zero for 0.2 s (gravity
    is the robot's: the arm floats and the press is released); every state of it."""
    robot = connect(host)
    result = press(robot, os.environ.get("SERVO", "cartesian"))
    result["idle"] = idle(robot)
    try:
        states, error = run(robot.start_torque_control(), lambda *_: fr.Torques([0.0] * 7), 0.2)
    except fr.ControlException as exc:
        states, error = [], str(exc)
    result.update(torque=[sample(s) for s in states], error=error)
    return result


if __name__ == "__main__":
    scenario_main.run(globals())
