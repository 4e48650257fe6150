"""The motion-limit engine: every command, extrapolated waypoint and measured state judged.

Seed "Motion limits and discontinuities" and "Communication constraints": the
cycle's commands (and the substitute waypoints of lost cycles) go through their
generator's precedence table (``limits``) before they are applied; late
datagrams rewind an extrapolated run or are judged only; the safety controller
watches the measured state (2, 3, 4); 20 lost cycles are 25. Violations are
logged always and abort the motion (through the controller's reflex) only when
enforced. The engine works on the controller's arrays (``self.c``): the
reference, the cycle's command candidates, the modes and the accounting.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..sim.self_collision import close_link_pairs, closest_link_pair
from . import extrapolation, limits
from ._fast import count_nonzero
from .cartesian import CartesianGenerators
from .errors import ERROR_NAMES, Error
from .tables import (
    DELTA_T,
    INTERIOR_SPEED,
    JOINT_KERNEL,
    JOINT_VELOCITY_LIMIT_TOLERANCE,
    MAX_LOST_CYCLES,
)
from .violations import ViolationLog, latched_bits

if TYPE_CHECKING:
    from .controller import FciController


class MotionLimitEngine:
    """Judges what the controller is about to apply, and what the arm did."""

    def __init__(self, controller: FciController) -> None:
        self.c = controller
        n = controller.n
        #: violations logged (once per class per motion) and seen
        self.violations = ViolationLog(n)
        #: the measured EE position of the previous cycle (for the EE speed)
        self.ee_prev = np.zeros((n, 3))
        # The safety controller's check of measured dq: [dq | -dq] against the envelope's
        # halves, widened by the margin; first against the interior shortcut's bounds,
        # on [dq | q | -dq | -q] (tables.interior_bounds).
        t = controller.table
        tol, margin = JOINT_VELOCITY_LIMIT_TOLERANCE, controller.config.measured_velocity_margin
        self._measured_shift = tol - margin
        self._measured = np.zeros((n, 34))
        inside = t.interior_bounds(INTERIOR_SPEED, self._measured_shift)
        # sqrt(3) |v_i| <= v_max on every axis implies |v| <= v_max; the factor keeps the
        # rounding of the squares' sum on the safe side.
        axis = np.full(3, t.v_trans_max / np.sqrt(3.0) * (1.0 - 1e-9))
        self._measured_bounds = np.concatenate([inside[:14], axis, inside[14:], axis])
        self._signed_dq = np.zeros((n, 14))
        #: late datagrams applied (not recorded) this cycle: the servo's target
        self.late = np.zeros(n, dtype=bool)
        self.late_q = np.zeros((n, 7))
        self.late_dq = np.zeros((n, 7))
        # The fused mid-motion q_c check: [q_c | dq | ddq | dddq] against stacked bounds
        # (the joint range, the envelope — filled per cycle —, the acceleration and
        # jerk limits of the robot's table).
        # A fifth block, the reference's q, is compared against the interior of the
        # joint ranges, where a constant bound stands in for the envelope
        # (tables.interior_bounds); outside it, the exact envelope is filled in.
        self._stacked = np.zeros((n, 35))
        self._derivatives = [self._stacked[:, 7 * k : 7 * k + 7] for k in range(5)]
        # The joint-velocity fast path's implied acceleration and jerk, and the q_d the
        # command advances to.
        self._velocity_ddq = np.zeros((n, 7))
        self._velocity_dddq = np.zeros((n, 7))
        self._velocity_q = np.zeros((n, 7))
        #: the torque fast path's commanded rate (_torques_inside_limits)
        self._torque_rate = np.zeros((n, 7))
        inside = t.interior_bounds(INTERIOR_SPEED, tol)
        self._upper_interior = np.tile(
            np.concatenate([t.q_upper, inside[:7], t.ddq_max, t.dddq_max, inside[7:14]]), (n, 1)
        )
        self._lower_interior = np.tile(
            np.concatenate([t.q_lower, -inside[14:21], -t.ddq_max, -t.dddq_max, -inside[21:]]),
            (n, 1),
        )
        self._upper = self._upper_interior[:, :28].copy()
        self._lower = self._lower_interior[:, :28].copy()
        # The fused C copies of these checks (fci/_joint_rules.c), where built; the
        # q_c and dq_c checks need a position-based envelope (the FER's is constant).
        self._kernel = JOINT_KERNEL
        self._envelope_kernel = JOINT_KERNEL if t.envelope_table is not None else None
        #: the Cartesian generators (their history, checks and IK)
        self.cartesian = CartesianGenerators(self)

    def advance_commands(self) -> None:
        """Judge and apply the cycle's commands, or extrapolate the lost cycles.

        Seed "Motion limits and discontinuities": every command — and every
        extrapolated waypoint, which is checked, never clamped — goes through
        its generator's precedence table; a violation is logged always and,
        with enforcement on, the command is not applied and the motion aborts.
        """
        m = self.c.modes
        n = self.c.n
        ref = self.c.reference
        if count_nonzero(self.c._refused):
            self._judge_non_finite()
        started = self.c.accounting.started
        if m.n_tracking and count_nonzero(started):
            have = self.c._have
            q_c, dq_c = self.c._q_c, self.c._dq_c
            # Every robot answered and none opens its motion: the fast paths' case.
            plain = count_nonzero(have) == n and not count_nonzero(self.c._first)
            if plain and m.n_joint_position == n and self._positions_inside_limits(q_c):
                d = self._derivatives
                ref.record_applied(q_c, d[1], d[2], self.c.writer.message_id)
            elif plain and m.n_joint_velocity == n and self._velocities_inside_limits(dq_c):
                # What the general path records for an applied dq_c: q_d advances by dq_c
                # over the cycle, the implied acceleration is frozen.
                ref.record_applied(
                    self._velocity_q, dq_c, self._velocity_ddq, self.c.writer.message_id
                )
            else:  # the rule functions name any violation (and its precedence)
                self._advance_joints(started, have, q_c, dq_c)
        if m.n_cartesian and count_nonzero(started):
            self.cartesian.advance(started)
        n_torques = count_nonzero(self.c._have) if m.n_external else 0
        if n_torques == m.n_external == n and self._torques_inside_limits(self.c._tau_c):
            # What _advance_torques does for torques that pass: applied, and the opening
            # command's status ends for torque-only motions.
            self.c.tau_J_d[...] = self.c._tau_c
            if count_nonzero(self.c._first):
                self.c._first &= ~m.torque_only
        elif n_torques:  # the rule functions name any violation (and its precedence)
            self._advance_torques()

    def _torques_inside_limits(self, tau_c: np.ndarray) -> bool:
        """Every robot's tau_c passes rows 34 (range) and 32 (rate against the applied
        tau_J_d over one cycle): the torque fast path, with the arithmetic of
        ``limits.check_torque`` and none of its masks. Non-finite commands never get
        here (refused on arrival)."""
        t, rate = self.c.table, self._torque_rate
        np.subtract(tau_c, self.c.tau_J_d, out=rate)
        rate /= DELTA_T  # check_torque's interval(1): the same division, the same bits
        return not (
            count_nonzero(~(np.abs(tau_c) <= t.tau_max)) or count_nonzero(np.abs(rate) > t.dtau_max)
        )

    def _velocities_inside_limits(self, dq_c: np.ndarray) -> bool:
        """Every robot's dq_c passes every mid-motion dq_c row (15 acceleration, 15 jerk,
        13 envelope at q_d): the joint-velocity fast path.

        The arithmetic of ``limits.check_joint_velocity`` over one cycle against the
        reference, without its masks; leaves the implied acceleration in
        ``_velocity_ddq`` and the q_d it advances to, q_d + dq_c dt, in ``_velocity_q``.
        Non-finite commands never get here (refused on arrival).
        """
        ref, t = self.c.reference, self.c.table
        ddq, dddq = self._velocity_ddq, self._velocity_dddq
        if self._envelope_kernel is not None:  # the same arithmetic, fused
            return self._envelope_kernel.velocities_inside(
                dq_c, ref.q, ref.dq, ref.ddq, ddq, dddq, self._velocity_q, t.ddq_max,
                t.dddq_max, t.envelope_table, JOINT_VELOCITY_LIMIT_TOLERANCE,
            )  # fmt: skip
        np.subtract(dq_c, ref.dq, out=ddq)
        ddq /= DELTA_T  # divided, as the rule function does: bit-identical to the general path
        np.subtract(ddq, ref.ddq, out=dddq)
        dddq /= DELTA_T
        np.add(ref.q, dq_c * DELTA_T, out=self._velocity_q)
        upper, lower = t.velocity_envelope(ref.q)
        return not (
            count_nonzero(np.abs(ddq) > t.ddq_max)
            or count_nonzero(np.abs(dddq) > t.dddq_max)
            or count_nonzero(dq_c > upper)
            or count_nonzero(dq_c < lower)
        )

    def _positions_inside_limits(self, q_c: np.ndarray) -> bool:
        """Every robot's q_c passes every mid-motion q_c row (12, 14, 13, 15): the fast path.

        The same arithmetic as ``limits.check_joint_position`` (backward Euler over one
        cycle against the reference), fused: q_c and its three derivatives side by side
        in one (n, 28) row, compared once against the stacked bounds. Non-finite
        commands never get here (refused on arrival).
        """
        ref, x = self.c.reference, self._stacked
        if self._envelope_kernel is not None:  # the same arithmetic, fused
            return self._envelope_kernel.positions_inside(
                q_c,
                ref.q,
                ref.dq,
                ref.ddq,
                x,
                self._upper_interior,
                self._lower_interior,
                self.c.table.envelope_table,
                JOINT_VELOCITY_LIMIT_TOLERANCE,
            )
        dq, ddq, dddq, q_ref = self._derivatives[1:]
        x[:, :7] = q_c
        np.subtract(q_c, ref.q, out=dq)
        dq /= DELTA_T  # divided, as the rule functions do: bit-identical to the general path
        np.subtract(dq, ref.dq, out=ddq)
        ddq /= DELTA_T
        np.subtract(ddq, ref.ddq, out=dddq)
        dddq /= DELTA_T
        q_ref[...] = ref.q
        if not (count_nonzero(x > self._upper_interior) or count_nonzero(x < self._lower_interior)):
            return True
        # Undecided (near a stop, or fast): the exact envelope at the reference's q.
        upper, lower = self.c.table.velocity_envelope(ref.q)
        self._upper[:, 7:14] = upper
        self._lower[:, 7:14] = lower
        x = x[:, :28]
        return not (count_nonzero(x > self._upper) or count_nonzero(x < self._lower))

    def _advance_joints(
        self,
        started: np.ndarray,
        have: np.ndarray,
        q_c: np.ndarray,
        dq_c: np.ndarray,
        echo: np.ndarray | None = None,
        extrapolate_lost: bool = True,
    ) -> None:
        """The general (masked) path: commands, extrapolations and holds of joint motions.

        ``have`` marks the robots whose command (``q_c`` / ``dq_c``, echoing ``echo``,
        by default the open cycle's id) is applied and recorded as a real sample;
        with ``extrapolate_lost`` the other started joint motions lose the cycle.
        """
        m = self.c.modes
        ref = self.c.reference
        dt = DELTA_T
        if echo is None:
            echo = self.c.writer.message_id
        lost = started & ~have & m.tracking
        if not extrapolate_lost:
            lost = np.zeros_like(lost)
        extrapolate = lost & (self.c.accounting.lost_run < MAX_LOST_CYCLES)
        # Seed "What the sim does with a lost cycle": one substitute waypoint per
        # missed cycle at the frozen acceleration, semi-implicit (v += a dt; q += v dt).
        ex_q, ex_dq = extrapolation.position_step(ref.q, ref.dq, ref.ddq_frozen, dt)
        h = have[:, None]
        q_cand = np.where(h, q_c, ex_q)
        dq_cand = np.where(h, dq_c, ex_dq)
        first = self.c._first & have
        position = (have | extrapolate) & m.joint_position
        velocity = (have | extrapolate) & m.joint_velocity
        new_dq, new_ddq = ex_dq, ref.ddq_frozen
        if count_nonzero(position):
            pc = self._judge_positions(q_cand, position, first)
            real = (have & m.joint_position)[:, None]
            new_dq = np.where(real, pc.dq, new_dq)
            new_ddq = np.where(real, pc.ddq, new_ddq)
        if count_nonzero(velocity):
            vc = self._judge_velocities(dq_cand, velocity, first)
            real = (have & m.joint_velocity)[:, None]
            new_dq = np.where(real, dq_c, new_dq)
            new_ddq = np.where(real, vc.ddq, new_ddq)
            q_cand = np.where((velocity & have)[:, None], ref.q + dq_c * dt, q_cand)
        # Robots aborted by _judge are no longer tracking: apply to the rest only.
        apply = (position | velocity) & self.c.modes.tracking
        held = lost & ~extrapolate & self.c.modes.tracking
        ref.record_masked(apply, have & apply, q_cand, new_dq, new_ddq, held, echo)
        self.c._first &= ~have

    def late_joint_datagrams(self, commands: np.ndarray, late: np.ndarray, ids) -> None:
        """Seed "A datagram that turns up late replaces the guess it stood in for".

        Inside an extrapolated run, the datagram echoing the run's oldest unanswered
        id throws the run's guesses away and is differenced against the last
        command that actually arrived, over the one cycle it really travelled in
        the client's stream, and becomes the new real sample (a backlog draining
        in order rewinds datagram by datagram). Any other late datagram — a
        replay, a duplicate, a reordered packet — gets no rewind and never touches
        the history: it is judged against the reference as it stands (and can
        trip a spurious discontinuity, as the seed warns), but not applied.
        """
        ref = self.c.reference
        ids = ids.astype(np.uint64)
        # The run's oldest unanswered id is the one after the last real command's:
        # after each rewind the next datagram of an in-order backlog is again that.
        rewind = late & (ids == ref.real_echo + np.uint64(1))
        if count_nonzero(rewind):
            ref.rewind(rewind)
            never = np.zeros(self.c.n, dtype=bool)
            self._advance_joints(
                never,
                rewind,
                commands["q_c"],
                commands["dq_c"],
                echo=ids,
                extrapolate_lost=False,
            )
            # The sample stands for state e + 1; the history must stand for the last
            # published state: guess the cycles in between again, from the real sample
            # (a later datagram of the backlog rewinds them in turn).
            behind = self.c.writer.message_id.astype(np.int64) - ids.astype(np.int64) - 1
            behind = np.where(rewind, behind, 0)
            for j in range(int(behind.max())):
                rows = rewind & (behind > j) & self.c.modes.tracking
                if not count_nonzero(rows):
                    break
                self._advance_joints(rows, never, commands["q_c"], commands["dq_c"])
        judged = late & ~rewind & self.c.modes.tracking
        if count_nonzero(judged):
            self._judge_only(commands, judged, ids)
            self._apply_late(commands, judged & self.c.modes.tracking)

    def _apply_late(self, commands: np.ndarray, rows: np.ndarray) -> None:
        """The joint intents of late datagrams of ``rows``: q_c itself, or one cycle of dq_c
        from the reference (see :meth:`apply_late`)."""
        if not count_nonzero(rows):
            return
        m, ref = self.c.modes, self.c.reference
        position = rows & m.joint_position
        velocity = rows & m.joint_velocity
        self.apply_late(position, commands["q_c"], 0.0)
        self.apply_late(velocity, ref.q + commands["dq_c"] * DELTA_T, commands["dq_c"])

    def apply_late(self, rows: np.ndarray, q, dq) -> None:
        """Seed: a late datagram "is still applied — within a cycle a late command is the
        freshest intent there is" — but "never becomes a sample of your trajectory". Its
        joint intent (``q``, ``dq``; the IK's for a Cartesian datagram) drives the servo
        this cycle unless a fresh command supersedes it (:meth:`servo_reference`); the
        history the next command is judged against is untouched."""
        r = rows[:, None]
        np.copyto(self.late_q, q, where=r)
        np.copyto(self.late_dq, dq, where=r)
        self.late |= rows

    def servo_reference(
        self, q_ref: np.ndarray, dq_ref: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The servo's target this cycle: late intents where no fresh command arrived and
        the motion still runs (every generator's; the Cartesian ones after their IK)."""
        if not count_nonzero(self.late):
            return q_ref, dq_ref
        c = self.c
        rows = (self.late & ~c._have & c.modes.in_motion)[:, None]
        self.late[...] = False
        dq = np.zeros_like(q_ref) if dq_ref is None else dq_ref
        return np.where(rows, self.late_q, q_ref), np.where(rows, self.late_dq, dq)

    def _judge_only(self, commands: np.ndarray, rows: np.ndarray, ids: np.ndarray) -> None:
        """Check late commands of ``rows`` without recording them: each against the
        reference published in the state it answers, over one cycle — what it would
        have been judged against on time (a client that skipped states, or whose
        datagram was delayed, is not charged for the extrapolation that went on
        meanwhile). Older than the ring (a replay): the reference as it stands."""
        m = self.c.modes
        current = self.c.writer.message_id
        history = self.c.reference.published(np.where(rows, ids, current), int(current[0]))
        if count_nonzero(rows & m.joint_position):
            self._judge_positions(commands["q_c"], rows & m.joint_position, False, history)
        if count_nonzero(rows & m.joint_velocity):
            self._judge_velocities(commands["dq_c"], rows & m.joint_velocity, False, history)

    def _judge_positions(self, q_c, rows, first, history=None) -> limits.PositionCheck:
        """q_c of ``rows`` judged over one cycle against ``history`` (q, dq, ddq), by
        default the reference as it stands: logged, enforced."""
        return self._judge_joint_command(
            limits.check_joint_position,
            limits.describe_joint_position,
            (q_c, rows, first, history),
            self.c.reference.q,
            self.c.config.start_pose_tolerance,
        )

    def _judge_velocities(self, dq_c, rows, first, history=None) -> limits.VelocityCheck:
        """dq_c of ``rows`` judged over one cycle against ``history`` (default: as it stands)."""
        return self._judge_joint_command(
            limits.check_joint_velocity,
            limits.describe_joint_velocity,
            (dq_c, rows, first, history),
            self.c.reference.dq,
            self.c.config.start_velocity_tolerance,
        )

    def _judge_joint_command(self, check_rule, describe_rule, what, start, tolerance):
        """One joint rule (``check_rule``) over ``what`` = (command, rows, first, history)."""
        command, rows, first, history = what
        ref = self.c.reference
        q, dq, ddq = history if history is not None else (ref.q, ref.dq, ref.ddq)
        args = (command, q, dq, ddq, first, start, 1, self.c.table, tolerance)
        check = check_rule(*args)
        self._judge(check.error, rows, lambda i: describe_rule(i, *args))
        return check

    def _advance_torques(self) -> None:
        """Judge the arrived torques (34 range, 32 rate); a lost cycle keeps the last one."""
        m = self.c.modes
        rows = self.c._have & m.external
        args = (self.c._tau_c, self.c.tau_J_d.copy(), self.c._first & rows, 1, self.c.table)
        error = limits.check_torque(*args)
        if count_nonzero(error[rows] >= 0):
            self._judge(error, rows, lambda i: limits.describe_torque(i, *args))
            rows = rows & self.c.modes.external
        # A torque is not a waypoint: a lost cycle keeps the last one (seed "What
        # the sim does with a lost cycle": tau_J_d held).
        np.copyto(self.c.tau_J_d, self.c._tau_c, where=rows[:, None])
        self.c._first &= ~(rows & self.c.modes.torque_only)

    def _judge_non_finite(self) -> None:
        """Seed: a non-finite command is refused whatever the enforcement, and reported as
        the limits violation of the generator it arrived in (12 q_c, 13 dq_c, 34 tau_J_d)."""
        m = self.c.modes
        refused = self.c._refused & m.in_motion
        error = np.full(self.c.n, limits.NO_ERROR)
        error[refused & m.external] = Error.tau_j_range_violation
        error[refused & m.joint_velocity] = Error.joint_motion_generator_velocity_limits_violation
        error[refused & m.joint_position] = Error.joint_motion_generator_position_limits_violation
        # Cartesian: a pose that is no homogeneous transformation (NaN included) is 31,
        # refused whatever the enforcement; a non-finite twist 18, a non-finite elbow 17.
        error[refused & m.cartesian_velocity] = (
            Error.cartesian_motion_generator_velocity_limits_violation
        )
        error[refused & m.cartesian_position] = (
            Error.cartesian_position_motion_generator_invalid_frame
        )
        elbow = self.c._refused_elbow & refused
        error[elbow] = Error.cartesian_motion_generator_elbow_limit_violation
        self.c._refused_elbow[...] = False

        def describe(i: int) -> str:
            if error[i] == Error.cartesian_position_motion_generator_invalid_frame:
                return "O_T_EE_c is not a homogeneous transformation (refused)"
            return "non-finite commanded value (refused)"

        self._judge(error, refused, describe)
        self.c._refused[...] = False

    def _judge(self, error: np.ndarray, rows: np.ndarray, describe, extra=None) -> None:
        """Log every violation in ``rows``; abort those robots' motions when enforced.

        ``extra`` maps a robot to further bits its one abort latches (29 with 30)."""
        bad = rows & (error >= 0) & self.c.modes.in_motion
        if not count_nonzero(bad):
            return
        enforce = self.c.config.enforce_motion_limits
        for i in np.flatnonzero(bad).tolist():
            e = int(error[i])
            described = describe(i)
            message = described.message() if hasattr(described, "message") else str(described)
            self.violations.report(i, e, message, enforce)
            bits = latched_bits(e)
            if extra and i in extra:
                for b in extra[i]:
                    self.violations.report(i, b, message, enforce)
                bits = bits + extra[i]
            if enforce:
                self.c.reflex(i, bits)

    # -- the safety controller and the communication bound ------------------------------------

    def safety_controller(self) -> None:
        """Seed "joint_velocity_violation (3)", "cartesian_velocity_violation (4)",
        "self_collision_avoidance_violation (2)": on the measured state, every control
        mode, every cycle of a motion; 4 outranks 3; 2 is independent of both."""
        physics, w, table = self.c.physics, self.c.writer, self.c.table
        margin = self.c.config.measured_velocity_margin
        dq = physics.dq
        q = physics.q
        # Cheap booleans first; the rule functions name the error only on a trip.
        # One row [dq | q | v_ee | -dq | -q | -v_ee] against the shortcuts' bounds:
        # measured dq against the envelope at measured q, widened by the margin
        # ([upper + margin | -(lower - margin)]), on the interior shortcut; and the EE
        # speed per axis, where |v_i| <= v_max / sqrt(3) for every axis implies
        # |v| <= v_max. Written as "not inside", so that a NaN state is undecided.
        x = self._measured
        # The measured EE speed at F_T_EE: backward difference of the measured
        # O_T_EE position over the 1 ms cycle (equal to J(q) dq to first order).
        v_ee = x[:, 14:17]
        if self._kernel is not None:  # the same row and comparison, fused
            inside = self._kernel.measured_inside(
                dq, q, w.O_T_EE, self.ee_prev, x, self._measured_bounds
            )
        else:
            np.subtract(w.O_T_EE[:, 12:15], self.ee_prev, out=v_ee)
            v_ee *= 1.0 / DELTA_T
            x[:, :7] = dq
            x[:, 7:14] = q
            np.negative(x[:, :17], out=x[:, 17:])
            inside = count_nonzero(x <= self._measured_bounds) == x.size
        close = close_link_pairs(
            physics.model, physics.data, physics.layout, self.c.config.self_collision_distance
        )
        if inside and not count_nonzero(close):
            return
        # Undecided: exactly.
        signed = self._signed_dq
        signed[:, :7] = dq
        np.negative(dq, out=signed[:, 7:])
        fast = ~(signed <= table.velocity_envelope_halves(q, self._measured_shift))
        speed2 = np.einsum("ij,ij->i", v_ee, v_ee)
        if not (
            count_nonzero(fast)
            or count_nonzero(~(speed2 <= table.v_trans_max**2))
            or count_nonzero(close)
        ):
            return
        v_ee = v_ee.copy()
        e_joint = limits.check_measured_joint_velocity(dq, physics.q, table, margin)
        e_cart = limits.check_measured_cartesian_speed(v_ee, table)
        error = limits.safety_error(e_joint, e_cart)
        bad = self.c.modes.in_motion & ((error >= 0) | close)
        if not count_nonzero(bad):
            return
        enforce = self.c.config.enforce_motion_limits
        for i in np.flatnonzero(bad).tolist():
            bits = []
            if error[i] >= 0:
                e = int(error[i])
                if e == int(Error.cartesian_velocity_violation):
                    d = limits.describe_measured_cartesian_speed(i, v_ee, table)
                else:
                    d = limits.describe_measured_joint_velocity(
                        i, physics.dq, physics.q, table, margin
                    )
                self.violations.report(i, e, d.message() if d else ERROR_NAMES[e], enforce)
                bits.append(e)
            if close[i]:
                e = int(Error.self_collision_avoidance_violation)
                pair = closest_link_pair(physics.model, physics.data, physics.layout, i)
                where = f"link{pair[1]} / link{pair[2]} at {pair[0] * 1000:.1f} mm" if pair else ""
                self.violations.report(
                    i,
                    e,
                    f"{where}, limit {self.c.config.self_collision_distance * 1000:.0f} mm",
                    enforce,
                )
                bits.append(e)
            if enforce:
                self.c.reflex(i, bits)

    def communication_constraints(self) -> None:
        """Seed "Enabling the violation": 20 consecutive lost cycles latch 25 (opt-in)."""
        over = (self.c.accounting.lost_run >= MAX_LOST_CYCLES) & self.c.modes.in_motion
        enforce = self.c.config.enforce_comm_constraints
        e = int(Error.communication_constraints_violation)
        for i in np.flatnonzero(over).tolist():
            run = int(self.c.accounting.lost_run[i])
            self.violations.report(
                i, e, f"{run} consecutive lost cycles, limit {MAX_LOST_CYCLES}", enforce
            )
            if enforce:
                self.c.reflex(i, [e])
