"""The requests a client makes between cycles: Move, StopMove, AutomaticErrorRecovery,
the setters, a session's end and the env's reset.

Each is applied at a cycle boundary and answers at once, or later through an event
that :meth:`FciController.step` returns (Move's final status, recovery done). Move's
arguments are checked here (the modes, the asynchronous generator's caps); the
setters' values by ``fci/setters.py``, the collision thresholds by ``fci/contact/collision.py``
and the Cartesian stiffness by ``fci/impedance.py``.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod

import numpy as np

from ..sim.arm import ArmPhysics
from . import setters
from .accounting import CycleAccounting
from .async_position import AsyncPositionGenerator, refusal
from .cartesian.generators import CartesianGenerators
from .config import ControllerConfig
from .contact.sensing import ContactSensing
from .cycle_input import CycleInput
from .hold import IdleHold
from .impedance import CartesianImpedance
from .modes import JOINT_IMPEDANCE, Modes
from .recovery import RecoveryWait
from .reference import JointReference
from .state import StateWriter
from .violations import ViolationLog
from .wire import (
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
    state_motion_generator_mode,
)
from .wire.statuses import AutomaticErrorRecoveryStatus, MoveStatus, SetterStatus, StopMoveStatus

log = logging.getLogger("franka_sim_gym.fci")


class ControllerRequests(ABC):
    """The request API of :class:`~franka_sim_gym.fci.controller.FciController`.

    A base of the controller, not used alone: the controller owns the state named below
    and provides the motion's lifecycle the requests share with the cycle (the abstract
    methods at the end).
    """

    physics: ArmPhysics
    config: ControllerConfig
    modes: Modes
    writer: StateWriter
    reference: JointReference
    tau_J_d: np.ndarray
    hold: IdleHold
    errors: np.ndarray
    reflex_reason: np.ndarray
    accounting: CycleAccounting
    recovery: RecoveryWait
    cycle_input: CycleInput
    violations: ViolationLog
    asynchronous: AsyncPositionGenerator
    cartesian: CartesianGenerators
    impedance: CartesianImpedance
    contact: ContactSensing

    def move(
        self,
        robot: int,
        controller_mode: int,
        motion_generator_mode: int,
        use_async_motion_generator: bool = False,
        maximum_velocity=None,
    ) -> MoveStatus:
        """Move (command 1): kMotionStarted, or the rejection that is the only reply.

        A Move during a Move preempts the running one (answered kPreempted) and
        the new motion starts from the idle hold's standstill (docs/fci-behaviour.md "One Move
        at a time"). With ``use_async_motion_generator`` the robot's own generator moves
        toward the targets the client sends, within ``maximum_velocity`` (7 values, rad/s;
        fci/async_position.py): joint positions under an internal controller only.
        """
        i = robot
        mode = RobotMode(int(self.modes.robot_mode[i]))
        if mode in (RobotMode.kReflex, RobotMode.kAutomaticErrorRecovery):
            log.warning("robot %d: Move rejected: command not possible in mode %s", i, mode.name)
            return MoveStatus.kCommandNotPossibleRejected
        try:
            ctrl = MoveControllerMode(controller_mode)
            gen = MoveMotionGeneratorMode(motion_generator_mode)
        except ValueError:
            log.warning(
                "robot %d: Move rejected: invalid controller mode %r / motion generator mode %r",
                i,
                controller_mode,
                motion_generator_mode,
            )
            return MoveStatus.kInvalidArgumentRejected
        if gen == MoveMotionGeneratorMode.kNone and ctrl != MoveControllerMode.kExternalController:
            log.warning("robot %d: Move rejected: no motion generator, no external controller", i)
            return MoveStatus.kInvalidArgumentRejected
        if use_async_motion_generator:
            problem = refusal(maximum_velocity)
            if gen != MoveMotionGeneratorMode.kJointPosition:
                problem = f"the asynchronous generator runs joint positions, not {gen.name}"
            elif ctrl == MoveControllerMode.kExternalController:
                problem = "the asynchronous generator needs an internal controller"
            if problem is not None:
                log.warning("robot %d: asynchronous Move rejected: %s", i, problem)
                return MoveStatus.kInvalidArgumentRejected
        if self.modes.in_motion[i]:
            log.info("robot %d: Move during a Move: the running motion is preempted", i)
            self.end_motion(i, MoveStatus.kPreempted, hold_reference=False)
        q = self.physics.q[i].copy()
        self.modes.start(i, int(state_motion_generator_mode(gen)), int(ctrl))
        # The motion starts from the measured q (what its first command is judged
        # against); the idle hold holds the arm until that command arrives (fci/hold.py).
        self.reference.seed(i, q, int(self.writer.message_id[i]))
        self.tau_J_d[i] = 0.0
        # A new motion starts with last_motion_errors clear: it describes the
        # motion that was aborted, not the connection (as the robot does).
        self.reflex_reason[i] = False
        self.accounting.start_motion(i, int(self.writer.message_id[i]))
        self.cycle_input.start(i)
        self.violations.begin_motion(i)
        if self.modes.cartesian[i]:
            self.cartesian.start(i)
        if use_async_motion_generator:
            # The robot's generator answers from the first cycle on: no client start pose.
            self.asynchronous.start(i, q, maximum_velocity)
            self.accounting.started[i] = True
            self.cycle_input.first[i] = False
        self.write_modes(i)
        return MoveStatus.kMotionStarted

    def stop_move(self, robot: int) -> StopMoveStatus:
        """StopMove (command 2): ends the running motion (answered kPreempted); idle hold."""
        if self.modes.in_motion[robot]:
            self.end_motion(robot, MoveStatus.kPreempted, hold_reference=False)
        return StopMoveStatus.kSuccess

    def automatic_error_recovery(self, robot: int) -> AutomaticErrorRecoveryStatus | None:
        """AutomaticErrorRecovery (command 10): clears ``errors`` (not ``reflex_reason``).

        Returns None: the reply is deferred (an event) until the measured
        |dq| < 0.005 rad/s for 50 consecutive cycles or 0.7 s have passed
        (docs/fci-behaviour.md "Enabling the violation"). Refused during a running motion.
        The idle hold that caught the reflex holds on (fci/hold.py).
        """
        i = robot
        if self.modes.in_motion[i]:
            return AutomaticErrorRecoveryStatus.kCommandNotPossibleRejected
        self.errors[i] = False
        self.contact.clear(i)
        self.accounting.rearm(i)
        self.modes.set_robot_mode(i, int(RobotMode.kAutomaticErrorRecovery))
        self.recovery.begin(i)
        self.write_modes(i)
        return None

    def set_ne_to_ee(self, robot: int, NE_T_EE) -> SetterStatus:
        """SetNEToEE (command 8): moves F_T_EE = F_T_NE · NE_T_EE, where O_T_EE is measured."""
        status = setters.check_transform("SetNEToEE", robot, NE_T_EE)
        if status == SetterStatus.kSuccess:
            self.writer.set_end_effector(robot, NE_T_EE=np.asarray(NE_T_EE, dtype=float))
        return status

    def set_ee_to_k(self, robot: int, EE_T_K) -> SetterStatus:
        """SetEEToK (command 7): reflected in EE_T_K; moves K, where the external wrench is
        estimated and the Cartesian impedance servo holds the pose."""
        status = setters.check_transform("SetEEToK", robot, EE_T_K)
        if status == SetterStatus.kSuccess:
            self.writer.set_end_effector(robot, EE_T_K=np.asarray(EE_T_K, dtype=float))
        return status

    def set_load(self, robot: int, m_load: float, F_x_Cload, I_load) -> SetterStatus:
        """SetLoad (command 9): reflected in m_load / F_x_Cload / I_load, and in the robot's
        model: the drives carry its weight, the external-torque estimate expects it."""
        status = setters.check_load(robot, m_load, F_x_Cload, I_load)
        if status == SetterStatus.kSuccess:
            self.writer.set_load(robot, m_load, np.ravel(F_x_Cload), np.ravel(I_load))
        return status

    def set_joint_impedance(self, robot: int, K_theta) -> SetterStatus:
        """SetJointImpedance (command 4): the internal joint servo's stiffness, applied."""
        status = setters.check_joint_stiffness(robot, K_theta)
        if status == SetterStatus.kSuccess:
            self.physics.set_stiffness(np.array([robot]), np.asarray(K_theta, dtype=float))
        return status

    def set_collision_behavior(self, robot: int, thresholds) -> SetterStatus:
        """SetCollisionBehavior (command 3): the contact and collision thresholds, applied
        from the next cycle (``thresholds``: the payload's eight arrays by name,
        fci/contact/collision.py THRESHOLD_NAMES; libfranka's 4-argument form sends each pair
        twice). Non-finite or negative thresholds: kInvalidArgumentRejected."""
        return self.contact.configure(robot, thresholds)

    def set_cartesian_impedance(self, robot: int, K_x) -> SetterStatus:
        """SetCartesianImpedance (command 5): the Cartesian servo's stiffness along K's axes,
        applied from the next cycle (fci/impedance.py); out of range: refused."""
        return self.impedance.configure(robot, K_x)

    def acknowledge_setter(self, robot: int, name: str, values) -> SetterStatus:
        """SetGuidingMode: accepted, not simulated."""
        return setters.check_finite(name, robot, values)

    def end_session(self, robot: int) -> None:
        """A client disconnected: end its motion, reset what it configured, keep latched errors.

        NE_T_EE (so F_T_EE) resets on a new connection (docs/robot-state.md); a latched
        reflex survives until AutomaticErrorRecovery clears it, as on the robot.
        """
        if self.modes.in_motion[robot]:
            self.end_motion(robot, MoveStatus.kAborted, hold_reference=False)
        if self.recovery.waiting(robot):
            self.finish_recovery(robot)
        self.writer.reset_configuration(robot)
        self.contact.behavior.reset(robot)
        self.impedance.reset(robot)
        self.physics.set_stiffness(np.array([robot]), np.asarray(self.config.joint_stiffness))
        self.drop_events({robot})

    def reset(self, robots, q: np.ndarray) -> None:
        """Teleport ``robots`` to joint positions ``q`` at rest and clear everything.

        For the Gymnasium env's resets: errors, reflex_reason, motions and the
        configured frames are cleared; message ids keep increasing.
        """
        robots = np.atleast_1d(np.asarray(robots, dtype=np.intp))
        q = np.asarray(q, dtype=float).reshape(len(robots), 7)
        self.physics.reset_arms(robots, q)
        for k, i in enumerate(robots.tolist()):
            self.modes.end(i)
            self.asynchronous.end(i)
            self.clear_commanded(i)
            self.errors[i] = False
            self.reflex_reason[i] = False
            self.recovery.end(i)
            self.accounting.stop_motion(i)
            self.writer.reset_configuration(i)
            self.impedance.reset(i)
            physics = self.physics
            stiffness = self.impedance.stiffness[i]
            self.hold.keep(i, q[k], JOINT_IMPEDANCE, physics.kp[i], physics.kd[i], stiffness)
            self.write_modes(i)
        self.contact.reset(robots)
        self.cycle_input.have[robots] = False
        self.cycle_input.finish[robots] = False
        self.drop_events(set(robots.tolist()))
        self.publish()

    # -- the motion's lifecycle, shared with the cycle (fci/controller.py) ----------------------

    @abstractmethod
    def end_motion(
        self, i: int, status: MoveStatus, hold_reference: bool, robot_mode: int | None = None
    ) -> None:
        """End robot i's motion with ``status``; the idle hold takes the arm back."""

    @abstractmethod
    def clear_commanded(self, i: int) -> None:
        """Between motions nothing is commanded: dq_d, ddq_d, tau_J_d read zero."""

    @abstractmethod
    def finish_recovery(self, i: int) -> None:
        """AutomaticErrorRecovery is over for robot i: back to kIdle."""

    @abstractmethod
    def write_modes(self, i: int) -> None:
        """Write robot i's modes, errors and last_motion_errors into the state."""

    @abstractmethod
    def publish(self) -> None:
        """Write state k+1 from the current physics (no step) and publish it."""

    @abstractmethod
    def drop_events(self, robots: set[int]) -> None:
        """Forget the unsent events of ``robots``."""
