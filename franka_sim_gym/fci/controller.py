"""The simulated FCI controller: one call to :meth:`FciController.step` is one 1 ms cycle.

Deterministic and batch-first (architecture.md): no sockets, threads or clock;
every per-cycle quantity has a leading robot axis. Two ways in drive it:

* ``receive(commands, mask)`` hands over the RobotCommand datagrams that
  reached the robots since the last cycle (call it once per datagram batch,
  in arrival order);
* ``step()`` closes the cycle: applies or extrapolates the commanded signal,
  steps physics, runs the accounting and writes state k+1 into ``states``,
  the (n,) array in the v10 wire layout that *is* what the server sends.

Requests (Move, StopMove, AutomaticErrorRecovery, the setters) are applied
between cycles by the scalar methods below and answer immediately, or later
through the events ``step()`` returns.

The cycle branches on Python-int group counts (``modes.Modes``) so that when
every robot is in the same situation — always so for one robot — it runs
without masks; the masked path is the same arithmetic under ``np.where``.
"""

from __future__ import annotations

import logging

import numpy as np

from ..sim.arm import ArmPhysics
from ..sim.hand_load import hand_load
from . import frames, setters
from ._fast import count_nonzero, put_rows
from .accounting import CycleAccounting
from .config import ControllerConfig
from .engine import MotionLimitEngine
from .errors import ERROR_COUNT, error_names
from .events import Event, EventKind
from .log_limit import CycleLogLimit
from .modes import JOINT_POSITION, JOINT_VELOCITY, Modes
from .protocol import AutomaticErrorRecoveryStatus, MoveStatus, SetterStatus, StopMoveStatus
from .reference import JointReference
from .state import StateWriter
from .tables import MAX_LOST_CYCLES
from .wire import (
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
    state_motion_generator_mode,
)

log = logging.getLogger("franka_sim_gym.fci")


class FciController:
    """The robot's controller behind FCI, for ``physics.n`` robots.

    Args:
        physics: the simulated arms (one per robot).
        config: switches and sim choices; defaults are the socket server's.
    """

    def __init__(self, physics: ArmPhysics, config: ControllerConfig | None = None) -> None:
        self.physics = physics
        self.config = config or ControllerConfig()
        self.table = self.config.table
        n = self.n = physics.n
        self.modes = Modes(n)
        load = hand_load(physics.model, physics.layout) if physics.hand else None
        self.writer = StateWriter(n, ee_load=load)
        self.states = self.writer.states
        w = self.writer
        #: the commanded joint reference: the published q_d / dq_d / ddq_d themselves
        self.reference = JointReference(w.q_d, w.dq_d, w.ddq_d)
        #: the commanded torque (without gravity): the published tau_J_d itself
        self.tau_J_d = w.tau_J_d
        #: where the internal servo holds the arm between motions
        self.q_hold = physics.q.copy()
        self.accounting = CycleAccounting(n)
        self.errors = np.zeros((n, ERROR_COUNT), dtype=bool)
        self.reflex_reason = np.zeros((n, ERROR_COUNT), dtype=bool)
        #: AutomaticErrorRecovery waiting for standstill: cycles waited, -1 = none
        self._recovery_wait = np.full(n, -1, dtype=np.int64)
        self._recovery_settled = np.zeros(n, dtype=np.int64)
        self._n_recovering = 0
        # The command candidates of the open cycle (the last datagram applied wins).
        self._q_c = np.zeros((n, 7))
        self._dq_c = np.zeros((n, 7))
        self._tau_c = np.zeros((n, 7))
        self._have = np.zeros(n, dtype=bool)
        self._finish = np.zeros(n, dtype=bool)
        self._all_true = np.ones(n, dtype=bool)
        self._all_true.setflags(write=False)
        #: a non-finite command arrived (refused whatever the enforcement)
        self._refused = np.zeros(n, dtype=bool)
        self._log_limit = CycleLogLimit(log)  # warnings that can repeat every cycle
        #: of those, a Cartesian command refused for its elbow alone (named 17)
        self._refused_elbow = np.zeros(n, dtype=bool)
        #: the motion's opening command has not been judged yet
        self._first = np.zeros(n, dtype=bool)
        #: the motion-limit engine (checks, safety controller, communication bound)
        self.engine = MotionLimitEngine(self)
        self.violations = self.engine.violations
        self._events: list[Event] = []
        physics.set_stiffness(np.arange(n), np.asarray(self.config.joint_stiffness))
        for i in range(n):
            self._write_modes(i)
        self._publish()

    # -- convenience views ----------------------------------------------------------------------

    @property
    def robot_mode(self) -> np.ndarray:
        return self.modes.robot_mode

    @property
    def in_motion(self) -> np.ndarray:
        return self.modes.in_motion

    def error_names(self, robot: int) -> tuple[str, ...]:
        """The printed names of robot ``robot``'s current errors."""
        return error_names(self.errors[robot])

    # -- the cycle ------------------------------------------------------------------------------

    def receive(self, commands: np.ndarray, mask: np.ndarray) -> None:
        """Hand over one RobotCommand per robot where ``mask`` is set (arrival order matters).

        A command answers the open cycle when it echoes the id of the last
        published state (seed "The cycle contract"); an older id of the running
        motion is late and still applied; an id never published answers
        nothing. Commands reaching a robot with no motion running are ignored,
        as the robot ignores them (libfranka repeats its final command until it
        sees the motion ended).
        """
        m = self.modes
        if m.n_motion == 0:
            return
        n = self.n
        if m.n_motion < n:
            mask = mask & m.in_motion
        k = count_nonzero(mask)
        if k == 0:
            return
        ids = commands["message_id"]
        published = self.writer.message_id
        fresh = ids == published
        if k < n:
            fresh &= mask
        late = None
        if count_nonzero(fresh) == k:
            accepted = fresh
        else:
            late = mask & (ids < published) & (ids >= self.accounting.motion_first_id)
            accepted = fresh | late
            self._log_unanswerable(mask & ~accepted, ids)
        finite = self._finite(commands)
        if finite is not self._all_true and count_nonzero(finite) < n:
            refused = accepted & ~finite
            self._log_non_finite(refused)
            self._refused |= refused
            accepted = accepted & finite
        self.accounting.answered |= fresh
        if late is not None and m.n_cartesian:
            late_cartesian = late & m.cartesian & accepted
            if count_nonzero(late_cartesian):
                # Seed "A datagram that turns up late replaces the guess it stood in for",
                # as for joint motions: the one the extrapolated run is missing rewinds
                # the Cartesian history, the others are judged and drive the servo only.
                self.engine.cartesian.late_datagrams(commands, late_cartesian, ids)
                accepted = accepted & ~late_cartesian
        if late is not None and m.n_tracking:
            late_joint = late & m.tracking & accepted
            if count_nonzero(late_joint):
                # Late datagrams of joint motions are handled on arrival: the one
                # the extrapolated run is missing rewinds it, the others are judged.
                self.engine.late_joint_datagrams(commands, late_joint, ids)
                accepted = accepted & ~late_joint
        all_in = count_nonzero(accepted) == n
        if m.n_joint_position:
            put_rows(self._q_c, commands["q_c"], accepted, all_in)
        if m.n_joint_velocity:
            put_rows(self._dq_c, commands["dq_c"], accepted, all_in)
        if m.n_external:
            put_rows(self._tau_c, commands["tau_J_d"], accepted, all_in)
        if m.n_cartesian:
            self.engine.cartesian.take(commands, accepted)
        self._have |= accepted
        self.accounting.started |= accepted
        if m.n_torque_only == 0:
            finished = commands["motion_generation_finished"]
        elif m.n_torque_only == n:
            finished = commands["torque_command_finished"]
        else:
            finished = np.where(
                m.torque_only,
                commands["torque_command_finished"],
                commands["motion_generation_finished"],
            )
        if count_nonzero(finished):  # (the last command of a motion only)
            self._finish |= accepted & finished

    def step(self) -> list[Event]:
        """Run one 1 ms cycle and publish state k+1; returns the events it produced."""
        m = self.modes
        w = self.writer
        if m.n_motion:
            self.engine.advance_commands()
        # Physics: the internal joint servo tracks q_d / dq_d under a joint
        # generator and the hold setpoint otherwise; an external controller's
        # torque is applied with gravity added by the actuators.
        if m.n_tracking == self.n:
            q_ref, dq_ref = w.q_d, w.dq_d
        elif m.n_tracking == 0:
            q_ref, dq_ref = self.q_hold, None
        else:
            track = m.tracking[:, None]
            q_ref = np.where(track, w.q_d, self.q_hold)
            dq_ref = np.where(track, w.dq_d, 0.0)
        if m.n_cartesian:
            q_ref, dq_ref = self.engine.cartesian.servo(q_ref, dq_ref)
        # A late datagram's intent, where no fresh command superseded it (called every
        # cycle, so an intent never outlives the cycle it arrived in).
        q_ref, dq_ref = self.engine.servo_reference(q_ref, dq_ref)
        #: what the joint servo was given this cycle (for tests and viewers)
        self.servo_q = q_ref
        moving = m.n_motion > 0
        if moving:
            self.engine.ee_prev[...] = w.O_T_EE[:, 12:15]
        self.physics.step(q_ref, dq_ref, self.tau_J_d, m.external_arg)
        w.write_measured(self.physics)
        if moving:
            if m.n_motion:
                self.engine.safety_controller()
            acc = self.accounting
            acc.close_cycle(int(count_nonzero(acc.started)))
            if count_nonzero(acc.lost_run >= MAX_LOST_CYCLES):
                self.engine.communication_constraints()
            if count_nonzero(self._finish):
                for i in np.flatnonzero(self._finish & m.in_motion).tolist():
                    self._end_motion(i, MoveStatus.kSuccess, hold_reference=True)
                self._finish[...] = False
            self._have[...] = False
        if self._n_recovering:
            self._advance_recovery()
        self._publish_rest()
        return self.take_events()

    def reflex(self, i: int, bits: list[int]) -> None:
        """Abort robot i's motion: latch ``bits``, kReflex, Move answered kReflexAborted
        (after the state carrying the error is sent: events go out after the state)."""
        if not self.modes.in_motion[i]:
            self.errors[i, bits] = True
            self.reflex_reason[i, bits] = True
            self._write_modes(i)
            return
        self.errors[i, bits] = True
        self.reflex_reason[i, bits] = True
        self._end_motion(
            i, MoveStatus.kReflexAborted, hold_reference=False, robot_mode=int(RobotMode.kReflex)
        )

    def cycle(self, commands: np.ndarray | None = None, mask=None) -> list[Event]:
        """``receive`` (when commands are given) then ``step``: one whole cycle."""
        if commands is not None:
            self.receive(commands, np.ones(self.n, dtype=bool) if mask is None else mask)
        return self.step()

    def take_events(self) -> list[Event]:
        """The events produced since the last call (``step()`` returns them too)."""
        events, self._events = self._events, []
        return events

    def _publish(self) -> None:
        """Write state k+1 from the current physics (no step) and publish it."""
        self.writer.write_measured(self.physics)
        self._publish_rest()

    def _publish_rest(self) -> None:
        """Derived fields, q_d between motions, and publish state k+1."""
        m = self.modes
        w = self.writer
        physics = self.physics
        # Idle and under joint generators the desired/commanded pose and elbow
        # are the measured ones (seed "RobotState fields": O_T_EE_d / O_T_EE_c).
        w.O_T_EE_d[...] = w.O_T_EE
        w.O_T_EE_c[...] = w.O_T_EE
        w.elbow_d[...] = w.elbow
        w.elbow_c[...] = w.elbow
        if m.n_motion == 0:
            w.q_d[...] = physics.q  # between motions q_d is the measured q
        elif m.n_motion < self.n:
            np.copyto(w.q_d, physics.q, where=~m.in_motion[:, None])
        if m.n_cartesian:
            self.engine.cartesian.publish()
        w.publish(self.accounting.success_rate())
        if m.n_tracking:
            self.reference.remember(int(w.message_id[0]))
        if m.n_cartesian:
            self.engine.cartesian.remember(int(w.message_id[0]))

    # -- requests (between cycles) --------------------------------------------------------------

    def move(
        self,
        robot: int,
        controller_mode: int,
        motion_generator_mode: int,
        use_async_motion_generator: bool = False,
    ) -> MoveStatus:
        """Move (command 1): kMotionStarted, or the rejection that is the only reply.

        A Move during a Move preempts the running one (answered kPreempted) and
        the new motion starts from the idle hold's standstill (seed "One Move
        at a time").
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
            log.warning("robot %d: Move rejected: the asynchronous generator is not implemented", i)
            return MoveStatus.kCommandNotPossibleRejected
        if self.modes.in_motion[i]:
            log.info("robot %d: Move during a Move: the running motion is preempted", i)
            self._end_motion(i, MoveStatus.kPreempted, hold_reference=False)
        q = self.physics.q[i].copy()
        self.modes.start(i, int(state_motion_generator_mode(gen)), int(ctrl))
        self.reference.seed(i, q, int(self.writer.message_id[i]))
        self.q_hold[i] = q
        self.tau_J_d[i] = 0.0
        # A new motion starts with last_motion_errors clear: it describes the
        # motion that was aborted, not the connection (as the robot does).
        self.reflex_reason[i] = False
        self.accounting.start_motion(i, int(self.writer.message_id[i]))
        self._have[i] = self._finish[i] = self._refused[i] = False
        self._first[i] = True
        self.violations.begin_motion(i)
        if self.modes.cartesian[i]:
            self.engine.cartesian.start(i)
        self._write_modes(i)
        return MoveStatus.kMotionStarted

    def stop_move(self, robot: int) -> StopMoveStatus:
        """StopMove (command 2): ends the running motion (answered kPreempted); idle hold."""
        if self.modes.in_motion[robot]:
            self._end_motion(robot, MoveStatus.kPreempted, hold_reference=False)
        return StopMoveStatus.kSuccess

    def automatic_error_recovery(self, robot: int) -> AutomaticErrorRecoveryStatus | None:
        """AutomaticErrorRecovery (command 10): clears ``errors`` (not ``reflex_reason``).

        Returns None: the reply is deferred (an event) until the measured
        |dq| < 0.005 rad/s for 50 consecutive cycles or 0.7 s have passed
        (seed "Enabling the violation"). Refused during a running motion.
        """
        i = robot
        if self.modes.in_motion[i]:
            return AutomaticErrorRecoveryStatus.kCommandNotPossibleRejected
        self.errors[i] = False
        self.accounting.rearm(i)
        self.q_hold[i] = self.physics.q[i]
        self.modes.set_robot_mode(i, int(RobotMode.kAutomaticErrorRecovery))
        self._recovery_wait[i] = 0
        self._recovery_settled[i] = 0
        self._n_recovering = int(count_nonzero(self._recovery_wait >= 0))
        self._write_modes(i)
        return None

    def set_ne_to_ee(self, robot: int, NE_T_EE) -> SetterStatus:
        """SetNEToEE (command 8): moves F_T_EE = F_T_NE · NE_T_EE, where O_T_EE is measured."""
        status = setters.check_transform("SetNEToEE", robot, NE_T_EE)
        if status == SetterStatus.kSuccess:
            self.writer.set_end_effector(robot, NE_T_EE=np.asarray(NE_T_EE, dtype=float))
        return status

    def set_ee_to_k(self, robot: int, EE_T_K) -> SetterStatus:
        """SetEEToK (command 7): reflected in EE_T_K; no Cartesian impedance uses it."""
        status = setters.check_transform("SetEEToK", robot, EE_T_K)
        if status == SetterStatus.kSuccess:
            self.writer.set_end_effector(robot, EE_T_K=np.asarray(EE_T_K, dtype=float))
        return status

    def set_load(self, robot: int, m_load: float, F_x_Cload, I_load) -> SetterStatus:
        """SetLoad (command 9): reflected in m_load / F_x_Cload / I_load (not simulated)."""
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

    def acknowledge_setter(self, robot: int, name: str, values) -> SetterStatus:
        """SetCollisionBehavior, SetCartesianImpedance, SetGuidingMode: accepted, not simulated."""
        return setters.check_finite(name, robot, values)

    def end_session(self, robot: int) -> None:
        """A client disconnected: end its motion, reset what it configured, keep latched errors.

        The seed resets F_T_EE to identity on a new connection; a latched
        reflex survives until AutomaticErrorRecovery clears it, as on the robot.
        """
        if self.modes.in_motion[robot]:
            self._end_motion(robot, MoveStatus.kAborted, hold_reference=False)
        if self._recovery_wait[robot] >= 0:
            self._finish_recovery(robot)
        self.writer.reset_configuration(robot)
        self.physics.set_stiffness(np.array([robot]), np.asarray(self.config.joint_stiffness))
        self._events = [e for e in self._events if e.robot != robot]

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
            self.q_hold[i] = q[k]
            self._clear_commanded(i)
            self.errors[i] = False
            self.reflex_reason[i] = False
            self._recovery_wait[i] = -1
            self.accounting.stop_motion(i)
            self.writer.reset_configuration(i)
            self._write_modes(i)
        self._n_recovering = int(count_nonzero(self._recovery_wait >= 0))
        self._have[robots] = False
        self._finish[robots] = False
        dropped = set(robots.tolist())
        self._events = [e for e in self._events if e.robot not in dropped]
        self._publish()

    # -- internals ------------------------------------------------------------------------------

    def _end_motion(
        self, i: int, status: MoveStatus, hold_reference: bool, robot_mode: int | None = None
    ) -> None:
        """End robot i's motion with ``status``; the idle hold takes the arm back."""
        generator = int(self.modes.motion_generator_mode[i])
        if hold_reference and generator in (JOINT_POSITION, JOINT_VELOCITY):
            # A finished joint motion is held where it was commanded to end.
            self.q_hold[i] = self.reference.q[i]
        elif hold_reference and self.modes.cartesian[i]:
            # ... and a finished Cartesian motion where its last pose solved to.
            self.q_hold[i] = self.engine.cartesian.q_ik[i]
        else:
            self.q_hold[i] = self.physics.q[i]
        if self.modes.cartesian[i]:
            self.engine.cartesian.end(i)
        if robot_mode is None:
            mode = int(self.modes.robot_mode[i])
            robot_mode = mode if mode != RobotMode.kMove else int(RobotMode.kIdle)
        self.modes.end(i, robot_mode)
        self._clear_commanded(i)
        accounting = self.accounting
        summary = accounting.motion_summary(i)
        accounting.stop_motion(i)
        self._have[i] = self._finish[i] = self._first[i] = self._refused[i] = False
        self._write_modes(i)
        self._events.append(Event(i, EventKind.MOVE_FINISHED, int(status), *summary))

    def _clear_commanded(self, i: int) -> None:
        """Between motions nothing is commanded: dq_d, ddq_d, tau_J_d read zero."""
        self.reference.dq[i] = 0.0
        self.reference.ddq[i] = 0.0
        self.tau_J_d[i] = 0.0

    def _advance_recovery(self) -> None:
        waiting = self._recovery_wait >= 0
        still = np.all(np.abs(self.physics.dq) < self.config.recovery_velocity_threshold, axis=1)
        self._recovery_settled = np.where(waiting & still, self._recovery_settled + 1, 0)
        self._recovery_wait[waiting] += 1
        done = waiting & (
            (self._recovery_settled >= self.config.recovery_settle_cycles)
            | (self._recovery_wait >= self.config.recovery_max_cycles)
        )
        for i in np.flatnonzero(done).tolist():
            if self._recovery_settled[i] < self.config.recovery_settle_cycles:
                log.warning("robot %d: recovery answered at the 0.7 s cap before standstill", i)
            self._finish_recovery(i)
            status = int(AutomaticErrorRecoveryStatus.kSuccess)
            self._events.append(Event(i, EventKind.RECOVERY_FINISHED, status))

    def _finish_recovery(self, i: int) -> None:
        self._recovery_wait[i] = -1
        self._recovery_settled[i] = 0
        self._n_recovering = int(count_nonzero(self._recovery_wait >= 0))
        self.modes.set_robot_mode(i, int(RobotMode.kIdle))
        self._write_modes(i)

    def _finite(self, commands: np.ndarray) -> np.ndarray:
        """Per robot: every value of the active interface's command fields is finite."""
        m = self.modes
        n = self.n
        if m.n_joint_position == n:
            q_c = commands["q_c"]
            finite = np.isfinite(q_c)
            if count_nonzero(finite) == finite.size:  # the common case, without a reduce
                return self._all_true
            return finite.all(axis=1)
        if m.n_external == n and m.n_torque_only == n:
            return np.isfinite(commands["tau_J_d"]).all(axis=1)
        if m.n_cartesian == n and not count_nonzero(commands["valid_elbow"]):
            # Every robot in one Cartesian generator, no elbow: the common case.
            if m.n_cartesian_position == n:
                verdict = frames.is_homogeneous_wire(commands["O_T_EE_c"])
                return self._all_true if verdict is None else verdict
            if m.n_cartesian_velocity == n:
                finite = np.isfinite(commands["O_dP_EE_c"])
                if count_nonzero(finite) == finite.size:
                    return self._all_true
                return finite.all(axis=1)
        ok = np.ones(n, dtype=bool)
        if m.n_joint_position:
            ok &= ~m.joint_position | np.isfinite(commands["q_c"]).all(axis=1)
        if m.n_joint_velocity:
            ok &= ~m.joint_velocity | np.isfinite(commands["dq_c"]).all(axis=1)
        if m.n_external:
            ok &= ~m.external | np.isfinite(commands["tau_J_d"]).all(axis=1)
        if m.n_cartesian_position:
            # 31: libfranka's isHomogeneousTransformation (NaN fails it too).
            pose_ok = frames.is_homogeneous_wire(commands["O_T_EE_c"])
            if pose_ok is not None:
                ok &= ~m.cartesian_position | pose_ok
        if m.n_cartesian_velocity:
            ok &= ~m.cartesian_velocity | np.isfinite(commands["O_dP_EE_c"]).all(axis=1)
        if m.n_cartesian:
            elbow_ok = ~commands["valid_elbow"].astype(bool) | np.isfinite(commands["elbow_c"]).all(
                axis=1
            )
            self._refused_elbow |= m.cartesian & ok & ~elbow_ok
            ok &= ~m.cartesian | elbow_ok
        return ok

    def _log_unanswerable(self, bogus: np.ndarray, ids: np.ndarray) -> None:
        for i in np.flatnonzero(bogus).tolist():
            self._log_limit.warning(
                int(self.writer.message_id[i]),
                ("unanswerable", i),
                "robot %d: command with message_id %d answers no state of the running motion "
                "(last published %d); counted as lost",
                i,
                int(ids[i]),
                int(self.writer.message_id[i]),
            )

    def _log_non_finite(self, refused: np.ndarray) -> None:
        for i in np.flatnonzero(refused).tolist():
            gen = int(self.modes.motion_generator_mode[i])
            signal = {JOINT_POSITION: "q_c", JOINT_VELOCITY: "dq_c"}.get(gen, "tau_J_d")
            self._log_limit.warning(
                int(self.writer.message_id[i]),
                ("non-finite", i),
                "robot %d: non-finite value in the commanded %s; command refused",
                i,
                signal,
            )

    def _write_modes(self, i: int) -> None:
        m = self.modes
        self.writer.write_modes(
            i,
            int(m.motion_generator_mode[i]),
            int(m.controller_mode[i]),
            int(m.robot_mode[i]),
            self.errors[i],
            self.reflex_reason[i],
        )
