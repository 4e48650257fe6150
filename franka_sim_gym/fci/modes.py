"""Per-robot motion modes as arrays, with the group counts the cycle's fast paths branch on.

The robot's state machine (robot_mode, motion generator, controller) is kept
as (n,) arrays — never Python objects per arm (architecture.md "Batch
first") — plus Python-int counts of each group, recomputed at transitions, so
the 1 kHz cycle can take an unmasked path when every robot is in the same
situation (always the case for the socket server's single robot).
"""

from __future__ import annotations

import numpy as np

from .wire import ControllerMode, MotionGeneratorMode, RobotMode

JOINT_POSITION = int(MotionGeneratorMode.kJointPosition)
JOINT_VELOCITY = int(MotionGeneratorMode.kJointVelocity)
CARTESIAN_POSITION = int(MotionGeneratorMode.kCartesianPosition)
CARTESIAN_VELOCITY = int(MotionGeneratorMode.kCartesianVelocity)
NONE = int(MotionGeneratorMode.kNone)
IDLE = int(MotionGeneratorMode.kIdle)
EXTERNAL = int(ControllerMode.kExternalController)
JOINT_IMPEDANCE = int(ControllerMode.kJointImpedance)
CARTESIAN_IMPEDANCE = int(ControllerMode.kCartesianImpedance)


class Modes:
    """robot_mode / motion_generator_mode / controller_mode of n robots, and derived groups."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.robot_mode = np.full(n, int(RobotMode.kIdle), dtype=np.uint8)
        self.motion_generator_mode = np.full(n, IDLE, dtype=np.uint8)
        self.controller_mode = np.full(n, JOINT_IMPEDANCE, dtype=np.uint8)
        self.regroup()

    def start(self, i: int, generator: int, controller: int) -> None:
        """Robot i runs a Move with these (state-enum) modes."""
        self.robot_mode[i] = RobotMode.kMove
        self.motion_generator_mode[i] = generator
        self.controller_mode[i] = controller
        self.regroup()

    def end(
        self, i: int, robot_mode: int = int(RobotMode.kIdle), hold: int = JOINT_IMPEDANCE
    ) -> None:
        """Robot i's motion ended; the internal servo ``hold`` holds it (fci/hold.py),
        reported as the controller mode between motions."""
        self.robot_mode[i] = robot_mode
        self.motion_generator_mode[i] = IDLE
        self.controller_mode[i] = hold
        self.regroup()

    def set_robot_mode(self, i: int, robot_mode: int) -> None:
        self.robot_mode[i] = robot_mode
        self.regroup()

    def regroup(self) -> None:
        """Recompute the masks and counts (at transitions only, never per cycle)."""
        gen, ctrl = self.motion_generator_mode, self.controller_mode
        self.in_motion = self.robot_mode == RobotMode.kMove
        self.joint_position = self.in_motion & (gen == JOINT_POSITION)
        self.joint_velocity = self.in_motion & (gen == JOINT_VELOCITY)
        #: a joint generator drives the internal servo's reference
        self.tracking = self.joint_position | self.joint_velocity
        #: a Cartesian generator drives the servo through IK (fci/cartesian/generators.py)
        self.cartesian_position = self.in_motion & (gen == CARTESIAN_POSITION)
        self.cartesian_velocity = self.in_motion & (gen == CARTESIAN_VELOCITY)
        self.cartesian = self.cartesian_position | self.cartesian_velocity
        #: q_d is a reference, not the measured q (docs/fci-behaviour.md "RobotState fields":
        #: the measured q between motions and during a Cartesian motion)
        self.keeps_q_d = self.in_motion & ~self.cartesian
        self.external = self.in_motion & (ctrl == EXTERNAL)
        #: the internal servo is the Cartesian impedance (a motion under kCartesianImpedance)
        self.cartesian_impedance = self.in_motion & (ctrl == CARTESIAN_IMPEDANCE)
        #: an external controller with no motion generator (startTorqueControl)
        self.torque_only = self.in_motion & (gen == NONE)
        self.n_motion = int(np.count_nonzero(self.in_motion))
        self.n_joint_position = int(np.count_nonzero(self.joint_position))
        self.n_joint_velocity = int(np.count_nonzero(self.joint_velocity))
        self.n_tracking = self.n_joint_position + self.n_joint_velocity
        self.n_cartesian_position = int(np.count_nonzero(self.cartesian_position))
        self.n_cartesian_velocity = int(np.count_nonzero(self.cartesian_velocity))
        self.n_cartesian = self.n_cartesian_position + self.n_cartesian_velocity
        self.n_external = int(np.count_nonzero(self.external))
        self.n_torque_only = int(np.count_nonzero(self.torque_only))
        self.n_cartesian_impedance = int(np.count_nonzero(self.cartesian_impedance))
        #: what physics.step takes for ``external``: None, True or a mask
        if self.n_external == 0:
            self.external_arg = None
        elif self.n_external == self.n:
            self.external_arg = True
        else:
            self.external_arg = self.external
