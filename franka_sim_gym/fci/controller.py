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
between cycles by the scalar methods the controller takes from
:class:`~franka_sim_gym.fci.requests.ControllerRequests` (fci/requests.py); they
answer immediately, or later through the events ``step()`` returns.

The controller owns the pieces and hands each what it needs: the cycle's
``CycleInput`` to the joint and Cartesian generators (peers), the measured state to
the safety controller; the engine returns verdicts, which the controller applies
(:meth:`FciController.reflex`).
"""

from __future__ import annotations

import logging

import numpy as np

from ..reality import DrawBatch
from ..sim.arm import ArmPhysics
from ..sim.hand_load import hand_load
from ..sim.kinematics import ArmKinematics
from . import arrival, frames
from .accounting import CycleAccounting
from .async_position import AsyncPositionGenerator
from .cartesian.generators import CartesianGenerators
from .config import ControllerConfig
from .contact.sensing import ContactSensing
from .cycle_input import CycleInput
from .engine import MotionLimitEngine
from .errors import ERROR_COUNT, error_names
from .events import Event, EventKind
from .hold import IdleHold, held_by
from .impedance import DEFAULT_CARTESIAN_STIFFNESS, CartesianImpedance
from .joint_generators import JointGenerators
from .late import LateIntents
from .log_limit import CycleLogLimit
from .modes import JOINT_POSITION, JOINT_VELOCITY, NONE, Modes
from .reality import RobotReality
from .recovery import RecoveryWait
from .reference import JointReference
from .requests import ControllerRequests
from .safety_controller import SafetyController
from .state import StateWriter
from .wire import (
    RobotMode,
)
from .wire.statuses import AutomaticErrorRecoveryStatus, MoveStatus

log = logging.getLogger("franka_sim_gym.fci")


class FciController(ControllerRequests):
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
        self.reference = JointReference(w.reference_columns)
        #: the commanded torque (without gravity): the published tau_J_d itself
        self.tau_J_d = w.tau_J_d
        physics.set_stiffness(np.arange(n), np.asarray(self.config.joint_stiffness))
        #: the idle hold: what holds the arm when no motion drives it (fci/hold.py)
        self.hold = IdleHold(physics.q, physics.kp, physics.kd, DEFAULT_CARTESIAN_STIFFNESS)
        self.accounting = CycleAccounting(n)
        self.errors = np.zeros((n, ERROR_COUNT), dtype=bool)
        self.reflex_reason = np.zeros((n, ERROR_COUNT), dtype=bool)
        #: AutomaticErrorRecovery waiting for standstill
        self.recovery = RecoveryWait(n, self.config)
        #: the open cycle's command candidates, who has one, who opens its motion
        self.cycle_input = CycleInput(n)
        #: warnings a client can make due every cycle, at most one line a second each
        self.warnings = CycleLogLimit(log)
        #: the motion-limit engine: judges what the rules found, returns verdicts
        self.engine = MotionLimitEngine(n, self.modes, self.config)
        self.violations = self.engine.violations
        #: late datagrams' joint intents for the open cycle
        self.late = LateIntents(n)
        # The generators, peers under the controller, and the safety controller.
        self.joint = JointGenerators(
            self.modes,
            self.reference,
            self.accounting,
            self.config,
            self.tau_J_d,
            w.message_id,
            self.engine,
            self.late,
            self.cycle_input,
        )
        #: the robot's asynchronous joint-position generator (fci/async_position.py)
        self.asynchronous = AsyncPositionGenerator(n, self.table, self.reference, self.engine)
        self.cartesian = CartesianGenerators(
            physics, w, self.modes, self.accounting, self.config, self.engine, self.late
        )
        #: the arrival's rules: fresh, late or answering nothing; refused or taken
        self.arrival = arrival.Arrival(
            self.modes,
            w.message_id,
            self.accounting.motion_first_id,
            self.accounting.answered,
            self.accounting.started,
            self.cycle_input,
            self.cartesian.candidates,
        )
        self.safety = SafetyController(
            physics, w.O_T_EE, self.modes, self.accounting, self.config, self.engine
        )
        #: the internal Cartesian impedance servo's stiffness and target
        self.impedance = CartesianImpedance(ArmKinematics(physics.model, physics.layout), n)
        #: the external-torque estimate, the wrench at K and the collision thresholds
        self.contact = ContactSensing(
            physics, w.field, self.engine, self.config.enforce_motion_limits
        )
        #: the robots' sensors, model and friction compensation under reality draws
        #: (fci/reality/); None: the ideal robot (built at the first draw that is not)
        self.reality: RobotReality | None = None
        self._events: list[Event] = []
        for i in range(n):
            self.write_modes(i)
        self.publish()

    def apply_reality(self, robots, draws: DrawBatch, scene: bool | None = None) -> None:
        """``robots`` become their draws' robots (rows of ``draws``): their arms and worlds
        (the physics), their sensors (docs/reality.md). An ideal draw on a controller that
        never had another changes nothing; the next reset or publish reads the new arms.
        ``scene``: the draws change the world's scene (a world with objects; None: if
        any of these draws does), decided at the first draw that is not ideal."""
        if self.reality is None:
            if all(d.robot_is_ideal for d in draws.draws):
                return
            if scene is None:
                scene = not all(d.scene_is_ideal for d in draws.draws)
            scene = bool(scene and self.physics.layout.scene_body)
            self.reality = RobotReality(self.physics, self.writer, scene)
            # The estimate reads the torque sensors' measurement.
            self.contact.tau_J = self.writer.tau_J
        self.reality.apply(robots, draws)

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
        published state (docs/fci-behaviour.md "The cycle contract"); an older id of the running
        motion is late and still applied; an id never published answers
        nothing. Commands reaching a robot with no motion running are ignored,
        as the robot ignores them (libfranka repeats its final command until it
        sees the motion ended).
        """
        m = self.modes
        if m.n_motion == 0:
            return
        cycle = self.cycle_input
        if self.asynchronous.count:
            targets = mask & self.asynchronous.active
            if np.count_nonzero(targets):
                # Targets for the robot's own generator, not commands of the open cycle.
                first_id = self.accounting.motion_first_id
                published = self.writer.message_id
                self.asynchronous.receive(
                    commands, targets, published, first_id, cycle, self.warnings
                )
                self._apply_verdicts()
                mask = mask & ~targets
        code = self.arrival.arrive(commands, mask)
        if code:
            self._arrival_found(commands, code)

    def _arrival_found(self, commands: np.ndarray, code: int) -> None:
        """What ``arrive`` left to the controller (fci/arrival.py): log the commands that
        answered nothing or were refused; hand late ones to their generators, then take
        the rest."""
        a = self.arrival
        if code & arrival.LOG:
            a.log(commands, self.writer.message_id, self.warnings)
        if not code & arrival.LATE:
            return
        m, cycle = self.modes, self.cycle_input
        ids = commands["message_id"]
        late, accepted = a.late, a.accepted
        if m.n_cartesian:
            late_cartesian = late & m.cartesian & accepted
            if np.count_nonzero(late_cartesian):
                # docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood
                # in for", as for joint motions: the one the extrapolated run is missing rewinds
                # the Cartesian history, the others are judged and drive the servo only.
                self.cartesian.late_datagrams(cycle, commands, late_cartesian, ids)
                self._apply_verdicts()
                accepted &= ~late_cartesian
        if m.n_tracking:
            late_joint = late & m.tracking & accepted
            if np.count_nonzero(late_joint):
                # Late datagrams of joint motions are handled on arrival: the one
                # the extrapolated run is missing rewinds it, the others are judged.
                self.joint.late_datagrams(commands, late_joint, ids)
                self._apply_verdicts()
                accepted &= ~late_joint
        a.take(commands)

    def step(self) -> list[Event]:
        """Run one 1 ms cycle and publish state k+1; returns the events it produced."""
        m = self.modes
        w = self.writer
        cycle = self.cycle_input
        if m.n_motion:
            # docs/fci-behaviour.md "Motion limits and discontinuities": every command and every
            # extrapolated waypoint judged by its generator; refused ones first.
            if np.count_nonzero(cycle.refused):
                self.engine.judge_non_finite(cycle)
            started = self.accounting.started
            if self.asynchronous.count:
                self.asynchronous.generate(cycle, self.accounting.answered)
            self.joint.advance(started)
            if m.n_cartesian and np.count_nonzero(started):
                self.cartesian.advance(cycle, started)
            self._apply_verdicts()
        q_ref, dq_ref, external, cartesian, gains = self._servo()
        #: what the joint servo was given this cycle (for tests and viewers)
        self.servo_q = q_ref
        moving = m.n_motion > 0
        if moving:
            self.safety.remember_ee()
        # The drives carry a load configured with SetLoad in every mode (the robot's
        # gravity compensation of its model); MuJoCo knows only what is physically there.
        load = self.contact.load_weight()
        reality = self.reality
        if reality is not None:  # and the robot's friction compensation, its model's gravity
            load = reality.model_terms(load)
        self.physics.step(
            q_ref, dq_ref, self.tau_J_d, external, cartesian, compensation=load, gains=gains
        )
        if reality is None:
            w.write_measured(self.physics)
        else:
            reality.write_measured(advance=True)
        self.contact.sense(m.in_motion, load)
        if moving:
            if m.n_motion:
                self.safety.check()
                self._apply_verdicts()
            if self.accounting.close_cycle():  # some robot at the 20-cycle bound
                self.safety.communication_constraints()
                self._apply_verdicts()
            if self.arrival.close():  # (have cleared) some command ends its motion
                for i in np.flatnonzero(cycle.finish & m.in_motion).tolist():
                    self.end_motion(i, MoveStatus.kSuccess, hold_reference=True)
                cycle.finish[...] = False
        if self.recovery.count:
            for i in self.recovery.advance(self.physics.dq):
                self.finish_recovery(i)
                status = int(AutomaticErrorRecoveryStatus.kSuccess)
                self._events.append(Event(i, EventKind.RECOVERY_FINISHED, status))
        self._publish_rest()
        return self.take_events()

    def _servo(self):
        """What physics is given this cycle: (q_ref, dq_ref, external, cartesian, gains).

        A motion drives the arm from its first command on: the internal joint servo
        tracks q_d / dq_d under a joint generator and the IK solution under a Cartesian
        one, the Cartesian servo (kCartesianImpedance) holds K at their forward
        kinematics, an external controller's torque is applied with gravity added by the
        actuators. Every other robot -- idle, or in a Move whose first command has not
        arrived -- is held by the idle hold: its servo, gains and configuration
        (fci/hold.py), so no switch steps what the physics sees.
        """
        m, w, hold = self.modes, self.writer, self.hold
        started = self.accounting.started
        driven = int(np.count_nonzero(started)) if m.n_motion else 0
        cartesian_rows = stiffness = None
        if driven == self.n:  # every robot in a motion that drives it
            if m.n_tracking == self.n:
                q_ref, dq_ref = w.q_d, w.dq_d
            elif m.n_tracking == 0:
                q_ref, dq_ref = hold.q, None
            else:
                track = m.tracking[:, None]
                q_ref = np.where(track, w.q_d, hold.q)
                dq_ref = np.where(track, w.dq_d, 0.0)
            if m.n_cartesian:
                q_ref, dq_ref = self.cartesian.servo(q_ref, dq_ref)
            external, gains = m.external_arg, None
            if m.n_cartesian_impedance:
                cartesian_rows = m.cartesian_impedance
        elif driven == 0:  # every robot held
            q_ref, dq_ref, external = hold.q, None, None
            gains = (hold.kp, hold.kd)
            if hold.n_cartesian:
                cartesian_rows, stiffness = hold.cartesian, hold.stiffness
        else:
            track = (m.tracking & started)[:, None]
            q_ref = np.where(track, w.q_d, hold.q)
            dq_ref = np.where(track, w.dq_d, 0.0)
            if m.n_cartesian:
                q_ref, dq_ref = self.cartesian.servo(q_ref, dq_ref, started)
            external = m.external & started
            d = started[:, None]
            gains = (np.where(d, self.physics.kp, hold.kp), np.where(d, self.physics.kd, hold.kd))
            rows = (m.cartesian_impedance & started) | (hold.cartesian & ~started)
            if np.count_nonzero(rows):
                cartesian_rows = rows
                stiffness = np.where(d, self.impedance.stiffness, hold.stiffness)
        # A late datagram's intent, where no fresh command superseded it (called every
        # cycle, so an intent never outlives the cycle it arrived in).
        q_ref, dq_ref = self.late.servo(q_ref, dq_ref, self.cycle_input.have, m.in_motion)
        cartesian = None
        if cartesian_rows is not None:
            EE_T_K = frames.from_wire(w.field["EE_T_K"])
            cartesian = self.impedance.target(cartesian_rows, q_ref, w.F_T_EE, EE_T_K, stiffness)
        return q_ref, dq_ref, external, cartesian, gains

    def _apply_verdicts(self) -> None:
        """The engine's verdicts, in the order it reached them: the reflex."""
        for verdict in self.engine.take_verdicts():
            self.reflex(verdict.robot, verdict.bits)

    def reflex(self, i: int, bits: list[int]) -> None:
        """Abort robot i's motion: latch ``bits``, kReflex, Move answered kReflexAborted
        (after the state carrying the error is sent: events go out after the state)."""
        if not self.modes.in_motion[i]:
            self.errors[i, bits] = True
            self.reflex_reason[i, bits] = True
            self.write_modes(i)
            return
        self.errors[i, bits] = True
        self.reflex_reason[i, bits] = True
        self.end_motion(
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

    def drop_events(self, robots: set[int]) -> None:
        """Forget the unsent events of ``robots`` (their session ended, or they were reset)."""
        self._events = [e for e in self._events if e.robot not in robots]

    def publish(self) -> None:
        """Write state k+1 from the current physics (no step) and publish it."""
        if self.reality is None:
            self.writer.write_measured(self.physics)
        else:  # the sensors' samples of this cycle: a robot that did not move reads the same
            self.reality.write_measured(advance=False)
        self._publish_rest()

    def _publish_rest(self) -> None:
        """Derived fields, q_d between motions, and publish state k+1."""
        m = self.modes
        w = self.writer
        physics = self.physics
        # Idle and under joint generators the desired/commanded pose and elbow
        # are the measured ones (docs/fci-behaviour.md "RobotState fields": O_T_EE_d /
        # O_T_EE_c); between motions and in a Cartesian one q_d is the measured q.
        w.copy_for_publish(physics.q, m.keeps_q_d)
        if m.n_cartesian:
            self.cartesian.publish()
        w.publish(self.accounting.success_rate())
        if m.n_tracking:
            self.reference.remember(int(w.message_id[0]))
        if m.n_cartesian:
            self.cartesian.remember(int(w.message_id[0]))

    # -- the motion's lifecycle (the cycle and the requests) ---------------------------------------

    def end_motion(
        self, i: int, status: MoveStatus, hold_reference: bool, robot_mode: int | None = None
    ) -> None:
        """End robot i's motion with ``status``; the idle hold takes the arm back."""
        m = self.modes
        if self.accounting.started[i]:
            # The motion drove the arm: the hold takes over from it (fci/hold.py). A
            # finished joint motion is held where it was commanded to end, a finished
            # Cartesian one where its last pose solved to, by the servo that ran it.
            generator = int(m.motion_generator_mode[i])
            reference = self.physics.q[i]
            if generator in (JOINT_POSITION, JOINT_VELOCITY):
                reference = self.reference.q[i]
            elif m.cartesian[i]:
                reference = self.cartesian.q_ik[i]
            finished = hold_reference and generator != NONE
            q, servo = held_by(
                finished, not m.external[i], int(m.controller_mode[i]), reference, self.physics.q[i]
            )
            physics = self.physics
            self.hold.keep(i, q, servo, physics.kp[i], physics.kd[i], self.impedance.stiffness[i])
        # (A motion that never drove the arm leaves the hold that held it.)
        if m.cartesian[i]:
            self.cartesian.end(i)
        if self.asynchronous.active[i]:
            self.asynchronous.end(i)
        if robot_mode is None:
            mode = int(m.robot_mode[i])
            robot_mode = mode if mode != RobotMode.kMove else int(RobotMode.kIdle)
        m.end(i, robot_mode, int(self.hold.controller[i]))
        self.clear_commanded(i)
        accounting = self.accounting
        summary = accounting.motion_summary(i)
        accounting.stop_motion(i)
        self.cycle_input.clear(i)
        self.write_modes(i)
        self._events.append(Event(i, EventKind.MOVE_FINISHED, int(status), *summary))

    def clear_commanded(self, i: int) -> None:
        """Between motions nothing is commanded: dq_d, ddq_d, tau_J_d read zero."""
        self.reference.dq[i] = 0.0
        self.reference.ddq[i] = 0.0
        self.tau_J_d[i] = 0.0

    def finish_recovery(self, i: int) -> None:
        """AutomaticErrorRecovery is over for robot i: back to kIdle."""
        self.recovery.end(i)
        self.modes.set_robot_mode(i, int(RobotMode.kIdle))
        self.write_modes(i)

    def write_modes(self, i: int) -> None:
        """Write robot i's modes, errors and last_motion_errors into the state."""
        m = self.modes
        self.writer.write_modes(
            i,
            int(m.motion_generator_mode[i]),
            int(m.controller_mode[i]),
            int(m.robot_mode[i]),
            self.errors[i],
            self.reflex_reason[i],
        )
