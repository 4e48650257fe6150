"""What the env configures on its robot before every episode, as a client would.

The internal servo a motion runs under (ControllerMode: ``"joint_impedance"``, the
default, or ``"cartesian_impedance"``), its stiffness (SetJointImpedance,
SetCartesianImpedance) and the collision thresholds (SetCollisionBehavior, libfranka's
4-argument form). None leaves the robot's own value. Values the robot would refuse are
a ValueError when the env is made, naming the argument.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fci.contact.collision import four_argument_form
from ..fci.controller import FciController
from ..fci.impedance import invalid_stiffness
from ..fci.setters import invalid_joint_stiffness
from ..fci.wire import MoveControllerMode
from ..fci.wire.statuses import SetterStatus

#: controller_mode's values: the internal servo under a motion generator.
CONTROLLER_MODES = {
    "joint_impedance": MoveControllerMode.kJointImpedance,
    "cartesian_impedance": MoveControllerMode.kCartesianImpedance,
}


@dataclass(frozen=True)
class RobotSettings:
    """The servo and the thresholds every episode starts with."""

    controller_mode: MoveControllerMode = MoveControllerMode.kJointImpedance
    joint_impedance: np.ndarray | None = None
    cartesian_impedance: np.ndarray | None = None
    collision_thresholds: dict | None = None

    @classmethod
    def from_arguments(
        cls,
        action_interface: str,
        controller_mode: str = "joint_impedance",
        joint_impedance=None,
        cartesian_impedance=None,
        collision_thresholds=None,
    ) -> RobotSettings:
        """Checked env arguments (see ``FrankaFCIEnv``); a ValueError names a bad one."""
        if controller_mode not in CONTROLLER_MODES:
            raise ValueError(
                f"unknown controller_mode {controller_mode!r}: expected one of "
                f"{tuple(CONTROLLER_MODES)}"
            )
        if action_interface == "torque" and controller_mode != "joint_impedance":
            raise ValueError("controller_mode: the torque interface is its own controller")
        joint = None
        if joint_impedance is not None:
            joint = np.asarray(joint_impedance, dtype=float)
            if joint.shape not in ((), (7,)):
                raise ValueError(f"joint_impedance {joint.tolist()}: 7 values or one")
            joint = np.broadcast_to(joint, (7,)).copy()
            why = invalid_joint_stiffness(joint)
            if why is not None:
                raise ValueError(f"joint_impedance: {why} Nm/rad")
        cartesian = None
        if cartesian_impedance is not None:
            cartesian = np.asarray(cartesian_impedance, dtype=float)
            why = invalid_stiffness(cartesian)
            if why is not None:
                raise ValueError(f"cartesian_impedance: {why}")
        thresholds = None
        if collision_thresholds is not None:
            thresholds = four_argument_form(collision_thresholds)
        return cls(CONTROLLER_MODES[controller_mode], joint, cartesian, thresholds)

    def move_controller(self, controller: MoveControllerMode) -> MoveControllerMode:
        """The controller mode of an interface's Move: ours, except the torque
        interface's external controller."""
        if controller == MoveControllerMode.kExternalController:
            return controller
        return self.controller_mode

    def apply(self, ctrl: FciController, i: int) -> None:
        """Send the settings to robot i (after a reset put it back to the defaults)."""
        statuses = []
        if self.joint_impedance is not None:
            statuses.append(ctrl.set_joint_impedance(i, self.joint_impedance))
        if self.cartesian_impedance is not None:
            statuses.append(ctrl.set_cartesian_impedance(i, self.cartesian_impedance))
        if self.collision_thresholds is not None:
            statuses.append(ctrl.set_collision_behavior(i, self.collision_thresholds))
        if any(s != SetterStatus.kSuccess for s in statuses):  # pragma: no cover - checked
            raise RuntimeError(f"robot {i} refused the env's settings: {statuses}")
