"""The joint motion generators (q_c, dq_c) and the torque interface (tau_J_d), per cycle.

docs/fci-behaviour.md "Motion limits and discontinuities" and "What the sim does with a lost cycle":
every command — and every extrapolated waypoint, which is checked, never clamped —
goes through its generator's precedence table (``limits``: ``check_joint_position``,
``check_joint_velocity``, ``check_torque``), is judged by the engine and, unless a
verdict aborts the motion, applied and recorded in the joint reference (the published
q_d / dq_d / ddq_d). Late datagrams rewind an extrapolated run or are judged only
(:meth:`JointGenerators.late_datagrams`).
"""

from __future__ import annotations

import numpy as np

from .. import native
from . import extrapolation, limits
from .accounting import CycleAccounting
from .config import ControllerConfig
from .cycle_input import CycleInput
from .engine import MotionLimitEngine
from .late import LateIntents
from .modes import Modes
from .reference import JointReference
from .tables import DELTA_T, JOINT_VELOCITY_LIMIT_TOLERANCE, MAX_LOST_CYCLES

#: the joint generators' cycle: the lost-cycle law, the rows, the record (their only text)
_CYCLE = native.require("fci.limits._joint", "JointCycle", "joint_record")


class JointGenerators:
    """Judge, apply and record the joint and torque commands of n robots.

    Args:
        modes, reference, accounting, config: the controller's (read; the reference
            is written).
        tau_J_d: (n, 7) the applied torque (the published field itself; written).
        published: (n,) the id of the last published state of each robot (read).
        engine: the judge; late: where late datagrams' intents go; cycle: the controller's
            cycle input (read; its ``first`` flags cleared). The cycle's C plan holds the
            engine's, the accounting's, the cycle input's and the reference's arrays: their
            owners write them in place, never rebind them.
    """

    def __init__(
        self,
        modes: Modes,
        reference: JointReference,
        accounting: CycleAccounting,
        config: ControllerConfig,
        tau_J_d: np.ndarray,
        published: np.ndarray,
        engine: MotionLimitEngine,
        late: LateIntents,
        cycle: CycleInput,
    ) -> None:
        self.modes = modes
        self.reference = reference
        self.accounting = accounting
        self.config = config
        self.table = config.table
        self.tau_J_d = tau_J_d
        self.published = published
        self.engine = engine
        self.late = late
        self.cycle = cycle
        n = modes.n
        #: the cycle's outputs: error, candidate, new q / dq / ddq (read where a row tripped)
        self._scratch = (
            np.full(n, -1, dtype=np.int64),
            *(np.zeros((n, 7)) for _ in range(4)),
        )
        constants, positional = self.table.joint_constants
        #: the cycle's C text over the arrays that stay (fci/limits/_joint.c JointCycle)
        self._cycle = _CYCLE.JointCycle(
            engine.aborted, cycle.first, accounting.lost_run, MAX_LOST_CYCLES,
            *self.reference.arrays, constants, positional, JOINT_VELOCITY_LIMIT_TOLERANCE,
            DELTA_T, *self._scratch,
        )  # fmt: skip

    def advance(self, started: np.ndarray) -> None:
        """The cycle's joint and torque commands of the ``started`` motions: judged and
        applied, or (joint motions) extrapolated for a lost cycle."""
        m, cycle = self.modes, self.cycle
        if m.n_tracking and np.count_nonzero(started):
            self._advance_joints(started, cycle.have, cycle.q_c, cycle.dq_c)
        if m.n_external and np.count_nonzero(cycle.have & m.external):
            self._advance_torques()

    def _advance_joints(
        self,
        started: np.ndarray,
        have: np.ndarray,
        q_c: np.ndarray,
        dq_c: np.ndarray,
        echo: np.ndarray | None = None,
        extrapolate_lost: bool = True,
    ) -> None:
        """Commands, extrapolations and holds of joint motions.

        ``have`` marks the robots whose command (``q_c`` / ``dq_c``, echoing ``echo``,
        by default the open cycle's id) is applied and recorded as a real sample;
        with ``extrapolate_lost`` the other started joint motions lose the cycle
        (docs/fci-behaviour.md "What the sim does with a lost cycle": one substitute
        waypoint per missed cycle at the frozen acceleration, checked, never clamped).
        One C call (fci/limits/_joint.c ``JointCycle.advance``: the lost-cycle law, the rows,
        the record); a robot whose candidate trips a row goes to the engine first.
        """
        m, config, cycle = self.modes, self.config, self.cycle
        if echo is None:
            echo = self.published
        pending = self._cycle.advance(
            q_c, dq_c, have, started, m.tracking, m.joint_position, m.joint_velocity, echo,
            extrapolate_lost, config.start_pose_tolerance, config.start_velocity_tolerance,
        )  # fmt: skip
        if pending:
            self._judge_pending(cycle.first & have, have, echo)
        if np.count_nonzero(cycle.first):  # (the opening commands only)
            cycle.first &= ~have

    def _judge_pending(self, first: np.ndarray, have: np.ndarray, echo: np.ndarray) -> None:
        """The robots :meth:`_advance_joints` left to the engine (a row tripped): judged as
        their generator's rules name it, then recorded unless a verdict aborts them."""
        m, ref = self.modes, self.reference
        error, candidate, new_q, new_dq, new_ddq = self._scratch
        tripped = error >= 0
        for rows, describe, start, tolerance in (
            (tripped & m.joint_position, limits.describe_joint_position, ref.q,
             self.config.start_pose_tolerance),
            (tripped & m.joint_velocity, limits.describe_joint_velocity, ref.dq,
             self.config.start_velocity_tolerance),
        ):  # fmt: skip
            if np.count_nonzero(rows):
                args = (candidate, ref.q, ref.dq, ref.ddq, first, start, 1, self.table, tolerance)
                self.engine.judge(error, rows, lambda i, a=args, d=describe: d(i, *a))
        _CYCLE.joint_record(
            self.engine.live(tripped), have, new_q, new_dq, new_ddq, echo, *ref.arrays
        )

    def late_datagrams(self, commands: np.ndarray, late: np.ndarray, ids: np.ndarray) -> None:
        """docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood in for".

        Inside an extrapolated run, the datagram echoing the run's oldest unanswered
        id throws the run's guesses away and is differenced against the last
        command that actually arrived, over the one cycle it really travelled in
        the client's stream, and becomes the new real sample (a backlog draining
        in order rewinds datagram by datagram). Any other late datagram — a
        replay, a duplicate, a reordered packet — gets no rewind and never touches
        the history: it is judged against the reference as it stands (and can
        trip a spurious discontinuity, as docs/fci-behaviour.md "A datagram that turns up late
        replaces the guess it stood in for" warns), but not applied.
        """
        ref = self.reference
        ids = ids.astype(np.uint64)
        # The run's oldest unanswered id is the one after the last real command's:
        # after each rewind the next datagram of an in-order backlog is again that.
        rewind = late & (ids == ref.real_echo + np.uint64(1))
        if np.count_nonzero(rewind):
            ref.rewind(rewind)
            never = np.zeros(len(rewind), dtype=bool)
            q_c, dq_c = commands["q_c"], commands["dq_c"]
            self._advance_joints(never, rewind, q_c, dq_c, ids, extrapolate_lost=False)
            # The sample stands for state e + 1; the history must stand for the last
            # published state: guess the cycles in between again, from the real sample
            # (a later datagram of the backlog rewinds them in turn).
            behind = self.published.astype(np.int64) - ids.astype(np.int64) - 1
            behind = np.where(rewind, behind, 0)
            for j in range(int(behind.max())):
                rows = rewind & (behind > j) & self.engine.live(self.modes.tracking)
                if not np.count_nonzero(rows):
                    break
                self._advance_joints(rows, never, q_c, dq_c)
        judged = late & ~rewind & self.engine.live(self.modes.tracking)
        if np.count_nonzero(judged):
            self._judge_only(commands, judged, ids)
            self._apply_late(commands, self.engine.live(judged))

    def _apply_late(self, commands: np.ndarray, rows: np.ndarray) -> None:
        """The joint intents of late datagrams of ``rows``: q_c itself, or one cycle of dq_c
        from the reference."""
        if not np.count_nonzero(rows):
            return
        m, ref = self.modes, self.reference
        self.late.apply(rows & m.joint_position, commands["q_c"], 0.0)
        dq_c = commands["dq_c"]  # q_d moved by one cycle of it, as the cycle records it
        self.late.apply(rows & m.joint_velocity, extrapolation.velocity_step(ref.q, dq_c), dq_c)

    def _judge_only(self, commands: np.ndarray, rows: np.ndarray, ids: np.ndarray) -> None:
        """Check late commands of ``rows`` without recording them: each against the
        reference published in the state it answers, over one cycle — what it would
        have been judged against on time (a client that skipped states, or whose
        datagram was delayed, is not charged for the extrapolation that went on
        meanwhile). Older than the ring (a replay): the reference as it stands."""
        m = self.modes
        current = self.published
        history = self.reference.published(np.where(rows, ids, current), int(current[0]))
        if np.count_nonzero(rows & m.joint_position):
            self._judge_positions(commands["q_c"], rows & m.joint_position, False, history)
        if np.count_nonzero(rows & m.joint_velocity):
            self._judge_velocities(commands["dq_c"], rows & m.joint_velocity, False, history)

    def _judge_positions(self, q_c, rows, first, history=None) -> limits.PositionCheck:
        """q_c of ``rows`` judged over one cycle against ``history`` (q, dq, ddq), by
        default the reference as it stands."""
        return self._judge_joint_command(
            limits.check_joint_position,
            limits.describe_joint_position,
            (q_c, rows, first, history),
            self.reference.q,
            self.config.start_pose_tolerance,
        )

    def _judge_velocities(self, dq_c, rows, first, history=None) -> limits.VelocityCheck:
        """dq_c of ``rows`` judged over one cycle against ``history`` (default: as it stands)."""
        return self._judge_joint_command(
            limits.check_joint_velocity,
            limits.describe_joint_velocity,
            (dq_c, rows, first, history),
            self.reference.dq,
            self.config.start_velocity_tolerance,
        )

    def _judge_joint_command(self, check_rule, describe_rule, what, start, tolerance):
        """One joint rule (``check_rule``) over ``what`` = (command, rows, first, history)."""
        command, rows, first, history = what
        ref = self.reference
        q, dq, ddq = history if history is not None else (ref.q, ref.dq, ref.ddq)
        args = (command, q, dq, ddq, first, start, 1, self.table, tolerance)
        check = check_rule(*args)
        self.engine.judge(check.error, rows, lambda i: describe_rule(i, *args))
        return check

    def _advance_torques(self) -> None:
        """Judge the arrived torques (34 range, 32 rate); a lost cycle keeps the last one."""
        cycle = self.cycle
        m = self.modes
        rows = cycle.have & m.external
        args = (cycle.tau_c, self.tau_J_d.copy(), cycle.first & rows, 1, self.table)
        error = limits.check_torque(*args)
        if np.count_nonzero(error[rows] >= 0):
            self.engine.judge(error, rows, lambda i: limits.describe_torque(i, *args))
            rows = self.engine.live(rows)
        # A torque is not a waypoint: a lost cycle keeps the last one (docs/fci-behaviour.md "What
        # the sim does with a lost cycle": tau_J_d held).
        np.copyto(self.tau_J_d, cycle.tau_c, where=rows[:, None])
        if np.count_nonzero(cycle.first):  # (the opening commands only)
            cycle.first &= ~(rows & m.torque_only)
