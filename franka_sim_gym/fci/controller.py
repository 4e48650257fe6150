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
"""

from __future__ import annotations

import logging

import numpy as np

from ..sim.arm import ArmPhysics
from . import frames
from .accounting import CycleAccounting
from .config import MAX_JOINT_STIFFNESS, ControllerConfig
from .errors import ERROR_COUNT, error_names
from .events import Event, EventKind
from .protocol import (
    AutomaticErrorRecoveryStatus,
    MoveStatus,
    SetterStatus,
    StopMoveStatus,
)
from .reference import JointReference
from .state import StateWriter
from .tables import MAX_LOST_CYCLES
from .wire import (
    ROBOT_COMMAND_DTYPE,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
    state_motion_generator_mode,
)

log = logging.getLogger("franka_sim_gym.fci")

_JOINT_POSITION = int(MotionGeneratorMode.kJointPosition)
_JOINT_VELOCITY = int(MotionGeneratorMode.kJointVelocity)
_NONE = int(MotionGeneratorMode.kNone)
_IDLE = int(MotionGeneratorMode.kIdle)
_EXTERNAL = int(ControllerMode.kExternalController)


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
        self.robot_mode = np.full(n, int(RobotMode.kIdle), dtype=np.uint8)
        self.motion_generator_mode = np.zeros(n, dtype=np.uint8)
        self.controller_mode = np.zeros(n, dtype=np.uint8)
        #: a Move is running (robot_mode kMove)
        self.in_motion = np.zeros(n, dtype=bool)
        #: where the internal servo holds the arm between motions
        self.q_hold = physics.q.copy()
        self.tau_J_d = np.zeros((n, 7))
        self.reference = JointReference(n)
        self.accounting = CycleAccounting(n)
        self.errors = np.zeros((n, ERROR_COUNT), dtype=bool)
        self.reflex_reason = np.zeros((n, ERROR_COUNT), dtype=bool)
        #: AutomaticErrorRecovery waiting for standstill: cycles waited / settled, -1 = none
        self._recovery_wait = np.full(n, -1, dtype=np.int64)
        self._recovery_settled = np.zeros(n, dtype=np.int64)
        # The command candidate of the open cycle (the last datagram applied wins).
        self._cmd = np.zeros(n, dtype=ROBOT_COMMAND_DTYPE)
        self._have_cmd = np.zeros(n, dtype=bool)
        self._finish = np.zeros(n, dtype=bool)
        self._events: list[Event] = []
        self.writer = StateWriter(n)
        self.states = self.writer.states
        physics.set_stiffness(np.arange(n), np.asarray(self.config.joint_stiffness))
        self._publish()

    # -- the cycle ----------------------------------------------------------------------------

    def receive(self, commands: np.ndarray, mask: np.ndarray) -> None:
        """Hand over one RobotCommand per robot where ``mask`` is set (arrival order matters).

        A command counts as the answer to the open cycle when it echoes the
        id of the last published state (seed "The cycle contract"); an older
        id is late and still applied; an id never published answers nothing.
        Commands reaching a robot with no motion running are ignored, as the
        robot ignores them (libfranka keeps repeating its final command until
        it sees the motion ended).
        """
        mask = np.asarray(mask, dtype=bool) & self.in_motion
        if not mask.any():
            return
        published = self.writer.message_id
        ids = commands["message_id"]
        fresh = mask & (ids == published)
        late = mask & (ids < published) & (ids >= self.accounting.motion_first_id)
        bogus = mask & ~(fresh | late)
        if bogus.any():
            for i in np.flatnonzero(bogus):
                log.warning(
                    "robot %d: command with message_id %d answers no published state "
                    "(last published %d, motion started at %d); counted as lost",
                    i,
                    int(ids[i]),
                    int(published[i]),
                    int(self.accounting.motion_first_id[i]),
                )
        accepted = fresh | late
        finite = self._finite(commands)
        refused = accepted & ~finite
        if refused.any():
            for i in np.flatnonzero(refused):
                log.warning(
                    "robot %d: non-finite value in the commanded %s; command refused",
                    i,
                    self._active_signal_name(i),
                )
        apply = accepted & finite
        self.accounting.mark_answered(fresh)
        self._cmd[apply] = commands[apply]
        self._have_cmd |= apply
        self.accounting.mark_first_command(apply)
        generator = self.motion_generator_mode
        finished = np.where(
            generator == _NONE,
            commands["torque_command_finished"],
            commands["motion_generation_finished"],
        )
        self._finish |= apply & finished.astype(bool)

    def step(self) -> list[Event]:
        """Run one 1 ms cycle and publish state k+1; returns the events it produced."""
        ref = self.reference
        moving = self.in_motion
        started = moving & self.accounting.started
        cmd = self._cmd
        have = self._have_cmd & started
        generator = self.motion_generator_mode
        # 1. the commanded signal: apply the cycle's command or extrapolate a lost cycle.
        jp = started & (generator == _JOINT_POSITION)
        jv = started & (generator == _JOINT_VELOCITY)
        if jp.any() or jv.any():
            ref.advance(
                position_cmd=have & jp,
                velocity_cmd=have & jv,
                extrapolate=started & ~have & (jp | jv),
                q_c=cmd["q_c"],
                dq_c=cmd["dq_c"],
                # Seed "Extrapolation stops at 20": past it the last value holds.
                can_extrapolate=self.accounting.lost_run < MAX_LOST_CYCLES,
            )
        external = moving & (self.controller_mode == _EXTERNAL)
        take_tau = have & external
        if take_tau.any():
            # A torque is not a waypoint: a lost cycle keeps the last one
            # (seed "What the sim does with a lost cycle": tau_J_d held).
            self.tau_J_d[take_tau] = cmd["tau_J_d"][take_tau]
        # 2. physics: the internal joint servo tracks q_d / dq_d (or the idle
        # hold); an external controller's torque is applied with gravity added.
        tracking = moving & ((generator == _JOINT_POSITION) | (generator == _JOINT_VELOCITY))
        q_ref = np.where(tracking[:, None], ref.q, self.q_hold)
        dq_ref = np.where(tracking[:, None], ref.dq, 0.0)
        self.physics.step(q_ref, dq_ref, self.tau_J_d, external)
        # 3. accounting, then the end of motions the client finished.
        self.accounting.close_cycle(started)
        finishing = self._finish & moving
        if finishing.any():
            for i in np.flatnonzero(finishing):
                self._end_motion(int(i), MoveStatus.kSuccess, hold_reference=True)
        self._advance_recovery()
        self._have_cmd[:] = False
        self._finish[:] = False
        self._publish()
        return self.take_events()

    def take_events(self) -> list[Event]:
        """The events produced since the last call (step() returns them too)."""
        events, self._events = self._events, []
        return events

    def cycle(
        self, commands: np.ndarray | None = None, mask: np.ndarray | None = None
    ) -> list[Event]:
        """``receive`` (when commands are given) then ``step``: one whole cycle."""
        if commands is not None:
            self.receive(commands, np.ones(self.n, bool) if mask is None else mask)
        return self.step()

    # -- requests (between cycles) ------------------------------------------------------------

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
        if self.robot_mode[i] == RobotMode.kReflex or self._recovery_wait[i] >= 0:
            log.warning(
                "robot %d: Move rejected: command not possible in mode %s",
                i,
                RobotMode(int(self.robot_mode[i])).name,
            )
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
            log.warning(
                "robot %d: Move rejected: no motion generator and no external controller", i
            )
            return MoveStatus.kInvalidArgumentRejected
        if gen in (
            MoveMotionGeneratorMode.kCartesianPosition,
            MoveMotionGeneratorMode.kCartesianVelocity,
        ):
            log.warning(
                "robot %d: Move rejected: the %s generator is not implemented yet in this build",
                i,
                gen.name,
            )
            return MoveStatus.kCommandNotPossibleRejected
        if use_async_motion_generator:
            log.warning(
                "robot %d: Move rejected: the asynchronous motion generator is not supported", i
            )
            return MoveStatus.kCommandNotPossibleRejected
        if self.in_motion[i]:
            log.info("robot %d: Move during a Move: the running motion is preempted", i)
            self._end_motion(i, MoveStatus.kPreempted, hold_reference=False)
        q = self.physics.q[i]
        self.in_motion[i] = True
        self.robot_mode[i] = RobotMode.kMove
        self.motion_generator_mode[i] = state_motion_generator_mode(gen)
        self.controller_mode[i] = int(ctrl)
        self.reference.seed(i, q)
        self.q_hold[i] = q
        self.tau_J_d[i] = 0.0
        # A new motion starts with last_motion_errors clear: it describes the
        # motion that was aborted, not the connection (issue: beyond the seed).
        self.reflex_reason[i] = False
        self.accounting.start_motion(i, int(self.writer.message_id[i]))
        self._publish_robot(i)
        return MoveStatus.kMotionStarted

    def stop_move(self, robot: int) -> StopMoveStatus:
        """StopMove (command 2): ends the running motion (answered kPreempted); idle hold."""
        if self.in_motion[robot]:
            self._end_motion(robot, MoveStatus.kPreempted, hold_reference=False)
            self._publish_robot(robot)
        return StopMoveStatus.kSuccess

    def automatic_error_recovery(self, robot: int) -> AutomaticErrorRecoveryStatus | None:
        """AutomaticErrorRecovery (command 10): clears ``errors`` (not ``reflex_reason``).

        Returns None: the reply is deferred (an event) until the measured
        |dq| < 0.005 rad/s for 50 consecutive cycles or 0.7 s have passed
        (seed "Enabling the violation"). A request during a running motion is
        refused with kCommandNotPossibleRejected.
        """
        i = robot
        if self.in_motion[i]:
            return AutomaticErrorRecoveryStatus.kCommandNotPossibleRejected
        self.errors[i] = False
        self.accounting.rearm(i)
        self.q_hold[i] = self.physics.q[i]
        self.robot_mode[i] = RobotMode.kAutomaticErrorRecovery
        self._recovery_wait[i] = 0
        self._recovery_settled[i] = 0
        self._publish_robot(i)
        return None

    def set_ne_to_ee(self, robot: int, NE_T_EE: np.ndarray) -> SetterStatus:
        """SetNEToEE (command 8): moves F_T_EE = F_T_NE · NE_T_EE, where O_T_EE is measured."""
        if not frames.is_homogeneous_transformation(NE_T_EE):
            log.warning("robot %d: SetNEToEE rejected: not a homogeneous transformation", robot)
            return SetterStatus.kInvalidArgumentRejected
        self.writer.set_end_effector(robot, NE_T_EE=np.asarray(NE_T_EE, float))
        self._publish_robot(robot)
        return SetterStatus.kSuccess

    def set_ee_to_k(self, robot: int, EE_T_K: np.ndarray) -> SetterStatus:
        """SetEEToK (command 7): reflected in EE_T_K; no Cartesian impedance uses it."""
        if not frames.is_homogeneous_transformation(EE_T_K):
            log.warning("robot %d: SetEEToK rejected: not a homogeneous transformation", robot)
            return SetterStatus.kInvalidArgumentRejected
        self.writer.set_end_effector(robot, EE_T_K=np.asarray(EE_T_K, float))
        return SetterStatus.kSuccess

    def set_load(self, robot: int, m_load: float, F_x_Cload, I_load) -> SetterStatus:
        """SetLoad (command 9): reflected in m_load / F_x_Cload / I_load (not simulated)."""
        values = np.concatenate([[m_load], np.ravel(F_x_Cload), np.ravel(I_load)]).astype(float)
        if values.shape != (13,) or not np.all(np.isfinite(values)) or m_load < 0:
            log.warning("robot %d: SetLoad rejected: invalid load %s", robot, values)
            return SetterStatus.kInvalidArgumentRejected
        self.writer.set_load(robot, values[0], values[1:4], values[4:])
        return SetterStatus.kSuccess

    def set_joint_impedance(self, robot: int, K_theta) -> SetterStatus:
        """SetJointImpedance (command 4): the internal joint servo's stiffness, applied."""
        K = np.asarray(K_theta, dtype=float).reshape(-1)
        if (
            K.shape != (7,)
            or not np.all(np.isfinite(K))
            or np.any(K < 0)
            or np.any(K > MAX_JOINT_STIFFNESS)
        ):
            log.warning(
                "robot %d: SetJointImpedance rejected: K_theta %s out of 0..%g",
                robot,
                K,
                MAX_JOINT_STIFFNESS,
            )
            return SetterStatus.kInvalidArgumentRejected
        self.physics.set_stiffness(np.array([robot]), K)
        return SetterStatus.kSuccess

    def acknowledge_setter(self, robot: int, name: str, values) -> SetterStatus:
        """Setters accepted but not simulated (SetCollisionBehavior, SetCartesianImpedance,
        SetGuidingMode): finite values are acknowledged, anything else is an invalid argument."""
        flat = np.asarray(values, dtype=float).reshape(-1)
        if not np.all(np.isfinite(flat)):
            log.warning("robot %d: %s rejected: non-finite argument", robot, name)
            return SetterStatus.kInvalidArgumentRejected
        log.info("robot %d: %s acknowledged (accepted, not simulated)", robot, name)
        return SetterStatus.kSuccess

    def end_session(self, robot: int) -> None:
        """A client disconnected: end its motion, reset the frames it set, keep latched errors.

        The seed resets F_T_EE to identity on a new connection; a latched
        reflex survives until AutomaticErrorRecovery clears it, as on the robot.
        """
        if self.in_motion[robot]:
            self._end_motion(robot, MoveStatus.kAborted, hold_reference=False)
        if self._recovery_wait[robot] >= 0:
            self._finish_recovery(robot)
        self.writer.reset_configuration(robot)
        self.physics.set_stiffness(np.array([robot]), np.asarray(self.config.joint_stiffness))
        self._events = [e for e in self._events if e.robot != robot]
        self._publish_robot(robot)

    def reset(self, robots, q: np.ndarray) -> None:
        """Teleport ``robots`` to joint positions ``q`` at rest and clear everything.

        For the Gymnasium env's resets: errors, reflex_reason, motions and the
        configured frames are cleared; message ids keep increasing.
        """
        robots = np.atleast_1d(np.asarray(robots, dtype=np.intp))
        q = np.asarray(q, dtype=float).reshape(len(robots), 7)
        self.physics.reset_arms(robots, q)
        for k, i in enumerate(robots):
            self.in_motion[i] = False
            self.robot_mode[i] = RobotMode.kIdle
            self.motion_generator_mode[i] = _IDLE
            self.controller_mode[i] = int(ControllerMode.kJointImpedance)
            self.q_hold[i] = q[k]
            self.tau_J_d[i] = 0.0
            self.errors[i] = False
            self.reflex_reason[i] = False
            self._recovery_wait[i] = -1
            self.accounting.stop_motion(int(i))
            self.writer.reset_configuration(int(i))
        self._have_cmd[robots] = False
        self._finish[robots] = False
        self._events = [e for e in self._events if e.robot not in set(robots.tolist())]
        self._publish()

    # -- internals ----------------------------------------------------------------------------

    def _end_motion(self, i: int, status: MoveStatus, hold_reference: bool) -> None:
        """End robot i's motion with ``status``; the idle hold takes the arm back."""
        tracking = self.motion_generator_mode[i] in (_JOINT_POSITION, _JOINT_VELOCITY)
        if hold_reference and tracking:
            # A finished joint motion is held where it was commanded to end.
            self.q_hold[i] = self.reference.q[i]
        else:
            self.q_hold[i] = self.physics.q[i]
        self.in_motion[i] = False
        if self.robot_mode[i] == RobotMode.kMove:
            self.robot_mode[i] = RobotMode.kIdle
        self.motion_generator_mode[i] = _IDLE
        self.controller_mode[i] = int(ControllerMode.kJointImpedance)
        self.tau_J_d[i] = 0.0
        self.accounting.stop_motion(i)
        self._events.append(Event(i, EventKind.MOVE_FINISHED, int(status)))

    def _advance_recovery(self) -> None:
        waiting = self._recovery_wait >= 0
        if not waiting.any():
            return
        still = np.all(np.abs(self.physics.dq) < self.config.recovery_velocity_threshold, axis=1)
        self._recovery_settled = np.where(waiting & still, self._recovery_settled + 1, 0)
        self._recovery_wait[waiting] += 1
        done = waiting & (
            (self._recovery_settled >= self.config.recovery_settle_cycles)
            | (self._recovery_wait >= self.config.recovery_max_cycles)
        )
        for i in np.flatnonzero(done):
            if self._recovery_settled[i] < self.config.recovery_settle_cycles:
                log.warning("robot %d: recovery answered at the 0.7 s cap before standstill", i)
            self._finish_recovery(int(i))
            self._events.append(
                Event(
                    int(i), EventKind.RECOVERY_FINISHED, int(AutomaticErrorRecoveryStatus.kSuccess)
                )
            )

    def _finish_recovery(self, i: int) -> None:
        self._recovery_wait[i] = -1
        self._recovery_settled[i] = 0
        self.robot_mode[i] = RobotMode.kIdle

    def _finite(self, commands: np.ndarray) -> np.ndarray:
        """Per robot: every value of the active interface's command fields is finite."""
        gen = self.motion_generator_mode
        ok = np.ones(self.n, dtype=bool)
        jp = gen == _JOINT_POSITION
        if jp.any():
            ok &= ~jp | np.all(np.isfinite(commands["q_c"]), axis=1)
        jv = gen == _JOINT_VELOCITY
        if jv.any():
            ok &= ~jv | np.all(np.isfinite(commands["dq_c"]), axis=1)
        ext = self.controller_mode == _EXTERNAL
        if ext.any():
            ok &= ~ext | np.all(np.isfinite(commands["tau_J_d"]), axis=1)
        return ok

    def _active_signal_name(self, i: int) -> str:
        names = {_JOINT_POSITION: "q_c", _JOINT_VELOCITY: "dq_c"}
        signal = names.get(int(self.motion_generator_mode[i]), "")
        if self.controller_mode[i] == _EXTERNAL:
            signal = f"{signal} / tau_J_d" if signal else "tau_J_d"
        return signal

    def _publish(self) -> None:
        """Write state k+1 for every robot (the wire array the server sends)."""
        moving = self.in_motion
        tracking = moving & (
            (self.motion_generator_mode == _JOINT_POSITION)
            | (self.motion_generator_mode == _JOINT_VELOCITY)
        )
        torque_only = moving & ~tracking
        ref = self.reference
        q = self.physics.q
        # q_d: the reference under a joint generator; the hold setpoint captured at
        # Move acceptance in a torque-only session; measured q between motions.
        q_d = np.where(tracking[:, None], ref.q, np.where(torque_only[:, None], self.q_hold, q))
        dq_d = np.where(tracking[:, None], ref.dq, 0.0)
        ddq_d = np.where(tracking[:, None], ref.ddq, 0.0)
        self.writer.write_cycle(
            physics=self.physics,
            q_d=q_d,
            dq_d=dq_d,
            ddq_d=ddq_d,
            tau_J_d=self.tau_J_d,
            motion_generator_mode=self.motion_generator_mode,
            controller_mode=self.controller_mode,
            robot_mode=self.robot_mode,
            errors=self.errors,
            reflex_reason=self.reflex_reason,
            success_rate=self.accounting.success_rate(),
        )

    def _publish_robot(self, i: int) -> None:
        """Refresh robot i's mode bytes after a request, without starting a new cycle."""
        self.writer.write_modes(
            i,
            int(self.motion_generator_mode[i]),
            int(self.controller_mode[i]),
            int(self.robot_mode[i]),
            self.errors[i],
            self.reflex_reason[i],
        )

    def error_names(self, robot: int) -> tuple[str, ...]:
        """The printed names of robot ``robot``'s current errors."""
        return error_names(self.errors[robot])
