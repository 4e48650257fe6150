"""The Cartesian motion generators: O_T_EE_c and O_dP_EE_c, judged, extrapolated and driven
through damped differential IK (docs/fci-behaviour.md "RobotState fields" (Cartesian rows), "What is
checked, and what it latches", "The joint side of a Cartesian command" and
"What the sim does with a lost cycle").

Per cycle, for every robot running a Cartesian generator whose accounting is open:

1. the candidate is the command that arrived, or — for a lost cycle — the
   extrapolation by the lost-cycle law (docs/fci-behaviour.md "What the sim does with a lost
   cycle"), up to 20 cycles (``step``);
2. its Cartesian derivatives (and the elbow's) are differenced against the history,
   a twist is integrated onto the IK target pose, the target is solved to joint space
   from the previous cycle's solution and the solution's acceleration and jerk form
   the joint side (``step``);
3. the precedence table names one error (``checks``, the rules in
   limits/cartesian.py), logged always, aborting under enforcement;
4. what survives is recorded (``record``) and its IK solution is the joint
   servo's reference (the arm follows the commanded pose).

Late datagrams are handled on arrival (:meth:`CartesianGenerators.late_datagrams`,
docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood in for"), as for
joint motions. The history lives in ``reference.CartesianReference`` (not in
JointReference): q_d keeps reporting the measured q during a Cartesian motion
(docs/fci-behaviour.md).
"""

from __future__ import annotations

import numpy as np

from ...sim.arm import ArmPhysics
from ..accounting import CycleAccounting
from ..config import ControllerConfig
from ..cycle_input import CycleInput
from ..engine import MotionLimitEngine
from ..frames import from_wire
from ..late import LateIntents
from ..modes import Modes
from ..state import StateWriter
from ..tables import MAX_LOST_CYCLES
from .checks import CartesianChecks
from .record import CartesianRecorder
from .reference import CartesianReference
from .step import Candidates, CartesianStepper, usable


class CartesianGenerators:
    """History, checks and IK of the Cartesian generators of n robots.

    Args:
        physics, writer, modes, accounting, config: the controller's (read; the
            writer's Cartesian fields are written by :meth:`publish`, in one C call with
            the history's arithmetic: fci/cartesian/_history.c, which holds the history's,
            the writer's and ``start_T``'s arrays, written in place, never rebound).
        engine: the judge; late: where late datagrams' intents go.
    """

    def __init__(
        self,
        physics: ArmPhysics,
        writer: StateWriter,
        modes: Modes,
        accounting: CycleAccounting,
        config: ControllerConfig,
        engine: MotionLimitEngine,
        late: LateIntents,
    ) -> None:
        n = self.n = physics.n
        self.physics = physics
        self.writer = writer
        self.modes = modes
        self.accounting = accounting
        self.engine = engine
        self.late = late
        #: the history (pose, twist, elbow, reported twist, IK joint history), its last
        #: real sample and the ring of published ones (fci/cartesian/reference.py)
        self.reference = CartesianReference(n)
        #: the pose a twist motion started from (O_T_EE_d / O_T_EE_c while it runs)
        self.start_T = np.tile(np.eye(4), (n, 1, 1))
        self.stepper = CartesianStepper(physics, modes, writer, self.reference, self.start_T)
        self.checks = CartesianChecks(modes, config, writer, engine)
        self.recorder = CartesianRecorder(modes, self.reference, self.stepper.plan)
        # The cycle's command candidates (the last datagram applied wins).
        self.T_cmd = np.tile(np.eye(4), (n, 1, 1))
        self.twist_cmd = np.zeros((n, 6))
        self.elbow_cmd = np.zeros((n, 2))
        self.elbow_valid = np.zeros(n, dtype=bool)
        #: the candidates' arrays, written by the arrival's rules (fci/arrival.py)
        self.candidates = (self.T_cmd, self.twist_cmd, self.elbow_cmd, self.elbow_valid)
        self._candidates = Candidates(*self.candidates)
        self._none = self.stepper.none

    @property
    def q_ik(self) -> np.ndarray:
        """(n, 7) the IK solution history's last sample: the joint servo's reference."""
        return self.reference.q_ik

    # -- motion lifecycle -------------------------------------------------------------------

    def start(self, i: int) -> None:
        """A Cartesian Move started: the history sits at rest at the measured pose."""
        w, h = self.writer, self.reference
        echo = int(w.message_id[i])
        h.start(i, echo)
        T = from_wire(w.O_T_EE[i])
        h.T[i] = T
        self.start_T[i] = T
        h.elbow[i] = w.elbow[i]
        h.q_ik[i] = self.physics.q[i]
        # A datagram echoing the state the Move was accepted in answers this history.
        h.remember_robot(i, echo)
        self.stepper.ik_failed_logged[i] = False

    # -- the cycle ----------------------------------------------------------------------------

    def advance(self, cycle: CycleInput, started: np.ndarray) -> None:
        """Judge, extrapolate and solve this cycle's Cartesian references."""
        rows = started & self.engine.live(self.modes.cartesian)
        k = np.count_nonzero(rows)
        if not k:
            return
        have = cycle.have & rows
        lost = self._none if np.count_nonzero(have) == k else rows & ~have
        self._cycle(cycle, have, lost, self._candidates, self.writer.message_id)

    def _cycle(
        self,
        cycle: CycleInput,
        have: np.ndarray,
        lost: np.ndarray,
        candidates: Candidates,
        echo: np.ndarray,
    ) -> None:
        """One cycle of the history: ``have`` robots record their candidate (a command that
        arrived, echoing ``echo``), ``lost`` ones are extrapolated (up to 20) or held."""
        h = self.reference
        extrapolate = held = self._none
        if np.count_nonzero(lost):
            h.begin_guesses(lost)
            extrapolate = lost & (self.accounting.lost_run < MAX_LOST_CYCLES)
            held = lost & ~extrapolate
        if np.count_nonzero(held):
            # docs/fci-behaviour.md "Extrapolation stops at 20": the last extrapolated value holds,
            # at rest.
            h.twist[held] = 0.0
            h.reported[held] = h.dreported[held] = 0.0
            h.dq_ik[held] = 0.0
        active = have | extrapolate
        if not np.count_nonzero(active):
            return
        first = cycle.first & have
        step = self.stepper.evaluate(h, candidates, have, extrapolate, first, active)
        self.checks.check(step, first, active)
        apply = self.engine.live(active)  # robots a verdict aborted are not recorded
        if not np.count_nonzero(apply):
            return
        self.recorder.record(step, have & apply, apply, extrapolate, first, echo)
        if np.count_nonzero(first):
            cycle.first &= ~have

    # -- late datagrams ------------------------------------------------------------------------

    def late_datagrams(
        self, cycle: CycleInput, commands: np.ndarray, late: np.ndarray, ids: np.ndarray
    ) -> None:
        """docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood in for".

        Inside an extrapolated run, the datagram echoing the run's oldest unanswered
        id throws the run's guesses away (pose, twist, elbow and the IK joint history
        return to the last real sample), is judged against that sample over one cycle
        — every Cartesian row, the joint side (29 / 30) included — and becomes the new
        real sample; the cycles up to the last published state are then guessed again
        from it, so a backlog draining in order rewinds datagram by datagram. Any other
        late datagram — a replay, a duplicate, a reordered packet — gets no rewind and
        never touches the history: it is judged against the history published in the
        state it answers, and its IK solution drives the servo this cycle unless a
        fresh command supersedes it.
        """
        h = self.reference
        ids = ids.astype(np.uint64)
        # The run's oldest unanswered id is the one after the last real command's:
        # after each rewind the next datagram of an in-order backlog is again that.
        rewind = late & (ids == h.real_echo + np.uint64(1))
        if np.count_nonzero(rewind):
            self._rewind(cycle, commands, rewind, ids)
        judged = late & ~rewind & self.engine.live(self.modes.cartesian)
        if np.count_nonzero(judged):
            self._judge_late(commands, judged, ids)

    def _late_candidates(self, commands: np.ndarray, rows: np.ndarray) -> Candidates:
        """The Cartesian fields of late datagrams as candidates (the cycle's own untouched)."""
        m = self.modes
        T = self.T_cmd.copy()
        pose = rows & m.cartesian_position
        if np.count_nonzero(pose):
            np.copyto(T, from_wire(commands["O_T_EE_c"]), where=pose[:, None, None])
        r = rows[:, None]
        twist = np.where(r, commands["O_dP_EE_c"], self.twist_cmd)
        elbow = np.where(r, commands["elbow_c"], self.elbow_cmd)
        return Candidates(T, twist, elbow, rows & commands["valid_elbow"].astype(bool))

    def _rewind(
        self, cycle: CycleInput, commands: np.ndarray, rows: np.ndarray, ids: np.ndarray
    ) -> None:
        """The datagram a run is missing replaces the guess it stood in for (see above)."""
        self.reference.rewind(rows)
        self._cycle(cycle, rows, self._none, self._late_candidates(commands, rows), ids)
        # The sample stands for state id + 1; the history must stand for the last
        # published state: guess the cycles in between again, from the real sample
        # (a later datagram of the backlog rewinds them in turn).
        behind = self.writer.message_id.astype(np.int64) - ids.astype(np.int64) - 1
        behind = np.where(rows, behind, 0)
        for j in range(int(behind.max())):
            again = rows & (behind > j) & self.engine.live(self.modes.cartesian)
            if not np.count_nonzero(again):
                break
            self._cycle(cycle, self._none, again, self._candidates, ids)

    def _judge_late(self, commands: np.ndarray, rows: np.ndarray, ids: np.ndarray) -> None:
        """Judge late datagrams of ``rows`` without recording them: each against the history
        published in the state it answers (older than the ring: the history as it stands),
        over one cycle; applied to the servo this cycle (docs/fci-behaviour.md "A datagram that
        turns up late replaces the guess it stood in for": a late datagram drives the servo for its
        cycle)."""
        current = self.writer.message_id
        h = self.reference.published(np.where(rows, ids, current), int(current[0]))
        candidates = self._late_candidates(commands, rows)
        step = self.stepper.evaluate(h, candidates, rows, self._none, self._none, rows)
        self.checks.check(step, self._none, rows)
        ik = step.ik
        apply = self.engine.live(rows & self.modes.cartesian) & usable(ik)
        if np.count_nonzero(apply):
            dq = np.where(ik.converged[:, None], step.dq, 0.0)
            self.late.apply(apply, ik.q, dq)

    # -- what the state reports ----------------------------------------------------------------

    def servo(self, q_ref: np.ndarray, dq_ref: np.ndarray | None, driven=None):
        """The joint servo's target: the IK solution for robots in a Cartesian motion (a
        late datagram's intent overrides it afterwards: ``LateIntents.servo``), of those
        ``driven`` (n,) by their motion where given (the others are held: fci/hold.py)."""
        h, m = self.reference, self.modes
        if driven is None and m.n_cartesian == self.n:  # every robot (copies: the
            return h.q_ik.copy(), h.dq_ik.copy()  # history moves on)
        rows = (m.cartesian if driven is None else m.cartesian & driven)[:, None]
        dq = np.zeros_like(q_ref) if dq_ref is None else dq_ref
        return np.where(rows, h.q_ik, q_ref), np.where(rows, h.dq_ik, dq)

    def publish(self) -> None:
        """O_T_EE_d / O_T_EE_c, O_dP_EE_d / O_dP_EE_c, O_ddP_EE_c and elbow_d / elbow_c of the
        robots in a Cartesian motion (docs/fci-behaviour.md "RobotState fields", the three
        regimes; one C call, fci/cartesian/_history.c ``History.publish``; their q_d is the
        measured q, as between motions: StateWriter.copy_for_publish)."""
        m = self.modes
        self.stepper.plan.publish(m.cartesian_position, m.cartesian_velocity)

    def remember(self, message_id: int) -> None:
        """The history as published in state ``message_id`` (what a late datagram
        answering it is judged against)."""
        self.reference.remember(message_id)

    def end(self, i: int) -> None:
        """The motion ended: the twist echo returns to zero."""
        w, h = self.writer, self.reference
        w.field["O_dP_EE_d"][i] = 0.0
        w.field["O_dP_EE_c"][i] = 0.0
        w.field["O_ddP_EE_c"][i] = 0.0
        h.twist[i] = 0.0
        h.reported[i] = h.dreported[i] = 0.0
        h.has_elbow[i] = False
        h.elbow_flag[i] = 0.0
