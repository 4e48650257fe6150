"""franky against the table: the reaction pattern of franky's own examples.

`python franky_contact_client.py SCENARIO HOST` prints one JSON line (scenario_main.py).
"""

from __future__ import annotations

import math

import franky
import numpy as np
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from franky_client import attempt

#: The flange pointing down 18 cm above the table (tests/sim/test_scene.py OVER_THE_TABLE).
OVER_THE_TABLE = [0.0, 0.6, 0.0, -1.9, 0.0, 2.5, math.pi / 4]


def scenario_reaction(host: str) -> dict:
    """A motion 30 cm straight down (through the table) with the reaction franky's
    examples attach, ``Measure.FORCE_Z < -5.0``, retreating 1 cm up when it fires.

    The collision thresholds are raised to 100 Nm / 100 N: franky's retreat starts from
    the motion's velocity and decelerates within its dynamics limits, while the joint
    servo keeps pressing (~1 N per ms at this speed), so at franky's default 30 N the
    robot's reflex would stop the retreat before it lifts off."""
    robot = franky.Robot(host, realtime_config=franky.RealtimeConfig.Ignore)
    robot.set_collision_behavior(100.0, 100.0)
    robot.relative_dynamics_factor = 0.02
    robot.move(franky.JointMotion(franky.JointState(OVER_THE_TABLE)))
    start = robot.current_cartesian_state.pose.end_effector_pose
    down = franky.Affine(start.translation + np.array([0.0, 0.0, -0.3]), start.quaternion)
    motion = franky.CartesianMotion(franky.RobotPose(down), franky.ReferenceType.Absolute)
    fired: list[tuple[float, float]] = []

    def on_contact(state, rel_time, abs_time) -> None:
        fired.append((float(state.O_F_ext_hat_K[2]), float(state.O_T_EE.translation[2])))

    # A relative target is in the end effector's frame, whose z points down here: -z is up.
    retreat = franky.CartesianMotion(
        franky.RobotPose(franky.Affine(np.array([0.0, 0.0, -0.01]))), franky.ReferenceType.Relative
    )
    reaction = franky.CartesianPoseReaction(franky.Measure.FORCE_Z < -5.0, retreat)
    reaction.register_callback(on_contact)
    motion.add_reaction(reaction)
    error = attempt(robot, motion)
    state = robot.state
    return {
        "error": error,
        "fired": fired,
        "z_start": float(start.translation[2]),
        "z_end": float(state.O_T_EE.translation[2]),
        "robot_mode": state.robot_mode.name,
        "current_errors": str(state.current_errors),
    }


if __name__ == "__main__":
    scenario_main.run(globals())
