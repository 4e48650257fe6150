"""franky: a press on the table, then the next motion (issue 36).

`python franky_press_client.py SCENARIO HOST` prints one JSON line (scenario_main.py).
franky fixes a Robot's controller mode when it connects (``Robot(...,
controller_mode=...)``), so the press runs on a Robot under SERVO (env: "cartesian" or
"joint") and the joint motion after it on a second Robot under JointImpedance; the
arm stays in the robot's idle hold across the reconnection.
"""

from __future__ import annotations

import math
import os
import time

import franky
import numpy as np
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from franky_client import attempt

#: The flange pointing down 18 cm above the table (tests/sim/test_scene.py OVER_THE_TABLE).
OVER_THE_TABLE = [0.0, 0.6, 0.0, -1.9, 0.0, 2.5, math.pi / 4]
#: As press_client.py: how far under the table each servo's press commands the flange.
DEPTH = {"cartesian": 0.02, "joint": 0.002}
MODE = {
    "cartesian": franky.ControllerMode.CartesianImpedance,
    "joint": franky.ControllerMode.JointImpedance,
}


def connect(host: str, mode) -> franky.Robot:
    robot = franky.Robot(host, realtime_config=franky.RealtimeConfig.Ignore, controller_mode=mode)
    robot.set_collision_behavior(100.0, 100.0)
    return robot


def sample(state) -> dict:
    return {
        "F": [float(v) for v in state.O_F_ext_hat_K],
        "z": float(state.O_T_EE.translation[2]),
        "mode": state.robot_mode.name,
    }


def to_height(
    robot: franky.Robot, z: float, factor: float, seen: list | None = None, hold_ms: int = 0
) -> None:
    """A Cartesian motion straight down (or up) to flange height ``z``, orientation kept,
    holding the target ``hold_ms`` before it finishes."""
    pose = robot.current_cartesian_state.pose.end_effector_pose
    target = franky.Affine(np.array([*pose.translation[:2], z]), pose.quaternion)
    waypoint = franky.CartesianWaypoint(
        franky.RobotPose(target),
        franky.ReferenceType.Absolute,
        relative_dynamics_factor=factor,
        hold_target_duration=franky.Duration(hold_ms),
    )
    motion = franky.CartesianWaypointMotion([waypoint])
    if seen is not None:
        motion.register_callback(lambda state, *_: seen.append(sample(state)))
    robot.move(motion)


def scenario_press_then_move(host: str) -> dict:
    """Over the table, SetCartesianImpedance([500] * 3 + [150] * 3), a Cartesian motion
    to 1 cm above the table, then (slowly) to DEPTH under it, held 1.5 s (the joint
    servo's press pushes sideways too, and MuJoCo's soft friction lets that relax over
    ~2 s: docs/robot-state.md "The idle hold"); 0.3 s of idle states;
    reconnected under JointImpedance, a JointMotion lifting joint 2 by 0.1 rad."""
    servo = os.environ.get("SERVO", "cartesian")
    robot = connect(host, MODE[servo])
    robot.move(franky.JointMotion(franky.JointState(OVER_THE_TABLE), relative_dynamics_factor=0.2))
    robot.set_cartesian_impedance([500.0] * 3 + [150.0] * 3)
    to_height(robot, 0.01, 0.1)
    pressing: list[dict] = []
    to_height(robot, -DEPTH[servo], 0.02, pressing, hold_ms=1500)
    idle = []
    end = time.monotonic() + 0.3
    while time.monotonic() < end:
        idle.append(sample(robot.state))
        time.sleep(0.01)
    del robot  # disconnect: the arm stays in the idle hold
    robot = connect(host, franky.ControllerMode.JointImpedance)
    before = sample(robot.state)
    q = np.asarray(robot.current_joint_state.position, dtype=float)
    q[1] -= 0.1
    lifting: list[dict] = []
    motion = franky.JointMotion(franky.JointState(q), relative_dynamics_factor=0.1)
    motion.register_callback(lambda state, *_: lifting.append(sample(state)))
    error = attempt(robot, motion)
    state = robot.state
    return {
        "press": pressing[-1],
        "idle": idle,
        "reconnected": before,
        "first": lifting[:3],
        "error": error,
        "after": sample(state),
        "last_motion_errors": str(state.last_motion_errors),
    }


if __name__ == "__main__":
    scenario_main.run(globals())
