"""The Cartesian motion generators: O_T_EE_c and O_dP_EE_c, judged, extrapolated and driven
through damped differential IK (seed "RobotState fields" (Cartesian rows), "What is
checked, and what it latches", "The joint side of a Cartesian command (29, 30)" and
"What the sim does with a lost cycle").

Per cycle, for every robot running a Cartesian generator whose accounting is open:

1. the candidate is the command that arrived, or — for a lost cycle — the
   extrapolation by the seed's law (pose: translation semi-implicit, rotation
   composed on the right by (omega + alpha dt) dt; twist at frozen twist
   acceleration; elbow[0] on the 1-D law, elbow[1] held), up to 20 cycles;
2. its Cartesian derivatives (and the elbow's) are differenced against the
   history; a twist is integrated onto the IK target pose;
3. the target is solved to joint space from the previous cycle's solution at
   F_T_EE (the elbow's joint 3 held where ``valid_elbow``), and the solution's
   acceleration and jerk form the joint side (29 / 30), skipped when the
   solver did not converge and silent on the opening command;
4. the precedence table names one error (limits/cartesian.py), logged always,
   aborting under enforcement; what survives is recorded and its IK solution
   is the joint servo's reference (the arm follows the commanded pose).

Late datagrams are handled on arrival (``late_datagrams``, seed "A datagram that
turns up late replaces the guess it stood in for"), as for joint motions: the one an
extrapolated run is missing rewinds the history to the last real sample and runs
steps 2-4 against it; any other is judged by steps 2-4 against the history published
in the state it answers and drives the servo for its cycle, never recorded.

The history lives in ``cartesian_reference.CartesianReference`` (not in
JointReference): q_d keeps reporting the measured q during a Cartesian motion, as
the seed says.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .. import native
from ..sim.kinematics import (
    USABLE_POSITION_ERROR,
    USABLE_ROTATION_ERROR,
    ArmKinematics,
    IkResult,
    einsum,
    rotation_exp,
)
from . import extrapolation
from ._fast import count_nonzero, put_rows
from .cartesian_reference import CartesianHistory, CartesianReference, columns
from .errors import Error
from .frames import from_wire, to_wire
from .limits import cartesian as rules
from .tables import DELTA_T, MAX_LOST_CYCLES

if TYPE_CHECKING:
    from .engine import MotionLimitEngine

log = logging.getLogger("franka_sim_gym.fci")
_DT = DELTA_T
#: IK samples after a rebase before the joint side is judged: a solution, then its
#: velocity; the acceleration (29) needs two and the jerk (30) three differences.
_WARM_ACCELERATION = 1
_WARM_JERK = 2


class Candidates(NamedTuple):
    """One command per robot, as a cycle's candidate: O_T_EE_c (row-major), O_dP_EE_c,
    elbow_c and valid_elbow (each generator reads its own field only)."""

    T: np.ndarray
    twist: np.ndarray
    elbow: np.ndarray
    elbow_valid: np.ndarray


class _Step(NamedTuple):
    """The candidates of one cycle differenced against a history and solved to joint space."""

    #: (n, 4, 4) the IK target: the commanded or extrapolated pose, or the twist's integral
    T: np.ndarray
    #: (n, 6) the commanded or extrapolated twist (the history's twist where neither)
    twist: np.ndarray
    #: (n, 3, 6) [twist, dtwist, ddtwist] while a twist motion runs, else None
    twist_stack: np.ndarray | None
    #: the pose's derivatives while a pose motion runs, else None
    d: rules.PoseDerivatives | None
    #: the extrapolated pose velocities (v, omega) of the lost cycles, else None
    pose_ex: tuple[np.ndarray, np.ndarray] | None
    #: the elbow stream (the commanded or extrapolated elbow and its derivatives)
    elbow: rules.ElbowStream
    #: elbow[0]'s extrapolated velocity (the history's where not extrapolated)
    de_ex: np.ndarray
    #: the IK solution and its backward differences; the joint side as judged
    ik: IkResult
    dq: np.ndarray
    joint: rules.JointSide
    #: (n, 3, 7) [q, dq, ddq] of the solution, side by side as the history keeps them
    solution: np.ndarray
    #: the kernel's screen found no Cartesian norm and no joint-side value of any robot
    #: near its limit (rules._quiet's verdict, before the cold jerk is zeroed)
    quiet: bool = False


class CartesianGenerators:
    """History, checks and IK of the Cartesian generators of n robots."""

    def __init__(self, engine: MotionLimitEngine) -> None:
        self.engine = engine
        c = engine.c
        self.c = c
        n = c.n
        physics = c.physics
        self.kinematics = ArmKinematics(physics.model, physics.layout, kernel=True)
        #: the history (pose, twist, elbow, reported twist, IK joint history), its last
        #: real sample and the ring of published ones (cartesian_reference.py)
        self.reference = CartesianReference(n)
        #: the pose a twist motion started from (O_T_EE_d / O_T_EE_c while it runs)
        self.start_T = np.tile(np.eye(4), (n, 1, 1))
        #: the IK did not converge (logged once per motion)
        self._ik_failed_logged = np.zeros(n, dtype=bool)
        # The cycle's command candidates (the last datagram applied wins).
        self.T_cmd = np.tile(np.eye(4), (n, 1, 1))
        self.twist_cmd = np.zeros((n, 6))
        self.elbow_cmd = np.zeros((n, 2))
        self.elbow_valid = np.zeros(n, dtype=bool)
        self._cycle_candidates = Candidates(
            self.T_cmd, self.twist_cmd, self.elbow_cmd, self.elbow_valid
        )
        self._none = np.zeros(n, dtype=bool)
        self._none.setflags(write=False)
        # The transpose of T_cmd: the wire's column-major layout, as a view to copy into.
        self._T_cmd_wire = self.T_cmd.transpose(0, 2, 1)
        # One cycle's scratch: a step is evaluated, judged and recorded before the next
        # (a late datagram's, a rewind's and the cycle's steps run one after another).
        T_twist = np.empty((n, 4, 4))  # a twist motion's IK target, its position and rotation
        self._T_twist = (T_twist, T_twist[:, :3, 3], T_twist[:, :3, :3])
        self._twist_stack = np.empty((n, 3, 6))  # [twist, dtwist, ddtwist]
        self._pose_stack = np.empty((n, 3, 6))  # the pose's derivatives
        self._joint = S = np.empty((n, 4, 7))  # [q, dq, ddq, dddq] of the IK solution
        # its views: q; [dq, ddq, dddq]; [ddq, dddq] (judged); [q, dq, ddq] (recorded); dq
        self._joint_views = (S[:, 0], S[:, 1:], S[:, 2:], S[:, :3], S[:, 1])
        self._spatial = np.empty((n, 6))  # a pose motion's reported twist
        # The elbow's derivatives while no elbow is streamed (read, never written).
        zeros = np.zeros(n)
        zeros.setflags(write=False)
        self._no_elbow = rules.ElbowDerivatives(zeros, zeros, zeros)
        #: the rules in C (fci/_cartesian_rules.c), or None: the numpy reference path only
        self._kernel = native.load("fci._cartesian_rules")
        #: the kernel's plain cycle (_plain_cycle), where the IK runs in C too and the
        #: kernel's history columns are this history's
        self._plain = (
            self._kernel
            if self._kernel is not None
            and self.kinematics.native_solve is not None
            and self._kernel.history_columns() == columns()
            else None
        )

    @property
    def q_ik(self) -> np.ndarray:
        """(n, 7) the IK solution history's last sample: the joint servo's reference."""
        return self.reference.q_ik

    # -- motion lifecycle -------------------------------------------------------------------

    def start(self, i: int) -> None:
        """A Cartesian Move started: the history sits at rest at the measured pose."""
        w, h = self.c.writer, self.reference
        echo = int(w.message_id[i])
        h.start(i, echo)
        T = from_wire(w.O_T_EE[i])
        h.T[i] = T
        self.start_T[i] = T
        h.elbow[i] = w.elbow[i]
        h.q_ik[i] = self.c.physics.q[i]
        # A datagram echoing the state the Move was accepted in answers this history.
        h.remember_robot(i, echo)
        self._ik_failed_logged[i] = False

    def take(self, commands: np.ndarray, accepted: np.ndarray) -> None:
        """Keep the Cartesian fields of the accepted commands as the cycle's candidates."""
        m = self.c.modes
        rows = accepted & m.cartesian
        k = count_nonzero(rows)
        if not k:
            return
        r = rows[:, None]
        # Each generator reads its own field only (the other is not looked at).
        if k == self.c.n:  # every robot: plain copies (the wire pose is T_cmd transposed)
            if m.n_cartesian_position:
                self._T_cmd_wire[...] = commands["O_T_EE_c"].reshape(k, 4, 4)
            if m.n_cartesian_velocity:
                self.twist_cmd[...] = commands["O_dP_EE_c"]
        else:
            if m.n_cartesian_position:
                np.copyto(self.T_cmd, from_wire(commands["O_T_EE_c"]), where=r[:, :, None])
            if m.n_cartesian_velocity:
                np.copyto(self.twist_cmd, commands["O_dP_EE_c"], where=r)
        valid = commands["valid_elbow"]
        if count_nonzero(valid) or count_nonzero(self.elbow_valid):
            np.copyto(self.elbow_cmd, commands["elbow_c"], where=r)
            np.copyto(self.elbow_valid, valid.astype(bool), where=rows)

    # -- the cycle ----------------------------------------------------------------------------

    def advance(self, started: np.ndarray) -> None:
        """Judge, extrapolate and solve this cycle's Cartesian references."""
        c = self.c
        rows = started & c.modes.cartesian
        k = count_nonzero(rows)
        if not k:
            return
        have = c._have & rows
        n_have = count_nonzero(have)
        if n_have == c.n and self._plain is not None and self._plain_cycle(have):
            return
        lost = self._none if n_have == k else rows & ~have
        self._cycle(have, lost, self._cycle_candidates, c.writer.message_id)

    def _plain_cycle(self, have: np.ndarray) -> bool:
        """_cycle in one kernel call (fci/_cartesian_rules.c plain_cycle) for the common
        cycle: every robot runs one generator and its command arrived, none opens its
        motion, no elbow is streamed, and then — as the kernel finds — every IK solve
        converged, every joint history is warm and the quiet screen passes, so that the
        precedence tables have nothing to judge. The same values as _cycle's (the kernel
        runs the same kernels' arithmetic); False, having recorded nothing, otherwise."""
        c, m, h = self.c, self.c.modes, self.reference
        n = c.n
        pose = m.n_cartesian_position == n
        if not (pose or m.n_cartesian_velocity == n):
            return False
        if count_nonzero(c._first) or count_nonzero(self.elbow_valid) or count_nonzero(
            h.has_elbow
        ):
            return False
        kin = self.kinematics
        recorded = self._plain.plain_cycle(
            pose, self.T_cmd, self.twist_cmd, h.buffer, self._T_twist[0],
            self._pose_stack if pose else self._twist_stack, self._joint, _DT,
            self._screen_limits(), self._ee_frame(), kin.native_solve, kin.rows_valid,
        )  # fmt: skip
        kin.solved_natively()
        if recorded:
            h.record_real(have, c.writer.message_id)
        return recorded

    def _cycle(
        self, have: np.ndarray, lost: np.ndarray, candidates: Candidates, echo: np.ndarray
    ) -> None:
        """One cycle of the history: ``have`` robots record their candidate (a command that
        arrived, echoing ``echo``), ``lost`` ones are extrapolated (up to 20) or held."""
        c, m, h = self.c, self.c.modes, self.reference
        extrapolate = held = self._none
        if count_nonzero(lost):
            h.begin_guesses(lost)
            extrapolate = lost & (c.accounting.lost_run < MAX_LOST_CYCLES)
            held = lost & ~extrapolate
        if count_nonzero(held):
            # Seed "Extrapolation stops at 20": the last extrapolated value holds, at rest.
            h.twist[held] = 0.0
            h.reported[held] = h.dreported[held] = 0.0
            h.dq_ik[held] = 0.0
        active = have | extrapolate if extrapolate is not self._none else have
        if not count_nonzero(active):
            return
        first = c._first & have
        step = self._evaluate(h, candidates, have, extrapolate, first, active)
        self._check(step, first, active)
        apply = active & m.cartesian  # robots aborted above are no longer in a Cartesian motion
        if not count_nonzero(apply):
            return
        real = have & apply
        self._record(step, real, apply, extrapolate, first)
        h.record_real(real, echo)
        if count_nonzero(first):
            c._first &= ~have

    def _evaluate(
        self,
        h: CartesianHistory,
        candidates: Candidates,
        have: np.ndarray,
        extrapolate: np.ndarray,
        first: np.ndarray,
        active: np.ndarray,
    ) -> _Step:
        """Difference ``have``'s candidates (and the extrapolation of ``extrapolate``)
        against the history ``h`` and solve them from its IK solution (seed "The
        difference formulas": over one cycle)."""
        c, m = self.c, self.c.modes
        n = c.n
        n_twist = m.n_cartesian_velocity
        # -- candidates: the command, or the seed's lost-cycle law ---------------------------
        pose_ex = None
        if count_nonzero(extrapolate):
            hv = have[:, None]
            x = extrapolate[:, None]
            T_ex, v_ex, w_ex = extrapolation.pose_step(
                h.T, h.v, h.a_frozen, h.omega, h.alpha_frozen, _DT
            )
            pose_ex = (v_ex, w_ex)
            tw_ex = extrapolation.velocity_step(h.twist, h.dtwist_frozen, _DT)
            twist = np.where(hv, candidates.twist, np.where(x, tw_ex, h.twist))
            T_pose = np.where(hv[:, :, None], candidates.T, T_ex)
        else:
            twist = candidates.twist if n_twist else h.twist
            T_pose = candidates.T
        if n_twist:
            T_tw = self._twist_target(h.T, twist)
            T_cand = (
                T_tw
                if n_twist == n
                else np.where(m.cartesian_position[:, None, None], T_pose, T_tw)
            )
        else:
            T_cand = T_pose
        elbow, de_ex = self._elbow(h, candidates, have, extrapolate)
        # -- derivatives ----------------------------------------------------------------------
        # The pose's derivatives judge pose motions (and feed their extrapolation and
        # reported twist); the twist's judge twist motions. Each only when one runs.
        F_T_EE = self._ee_frame()
        in_use = elbow.has is not self._none and bool(
            count_nonzero(elbow.has) or count_nonzero(elbow.had)
        )  # (_elbow's stream without an elbow has self._none)
        e_fixed = np.where(elbow.has, elbow.command[:, 0], np.nan) if in_use else None
        q, differences, judged, recorded, dq = self._joint_views
        quiet = False
        if self._kernel is not None and n in (m.n_cartesian_position, n_twist):
            # One generator for every robot: the kernel differences the candidates and the
            # IK solution in one call (the same values; see _fused).
            ik = self.kinematics.solve(T_cand, h.q_ik, F_T_EE, e_fixed, rows=active, out=q)
            d, twist_stack, quiet = self._fused(h, T_cand, twist, q, differences)
        else:
            d = None
            if m.n_cartesian_position:
                d = rules.pose_derivatives(T_cand, h.T, h.history, 1, out=self._pose_stack)
            twist_stack = self._twist_derivatives(h, twist) if n_twist else None
            # -- the joint side: IK from the previous solution -------------------------------
            ik = self.kinematics.solve(T_cand, h.q_ik, F_T_EE, e_fixed, rows=active, out=q)
            rules.joint_side(q, h.q_ik, h.dq_ik, h.ddq_ik, 1, out=differences)
        joint = rules.JointSide(judged, self._joint_checked(h, ik, first, active))
        return _Step(
            T_cand, twist, twist_stack, d, pose_ex, elbow, de_ex, ik, dq, joint, recorded, quiet
        )

    def _ee_frame(self) -> np.ndarray | None:
        """(n, 4, 4) F_T_EE the IK solves at, or None where every robot's is the flange."""
        w = self.c.writer
        return w.F_T_EE if w._any_custom_ee else None

    def _screen_limits(self) -> np.ndarray:
        """(20,) the kernels' quiet screen's limits (rules._quiet_limits, cached there)."""
        c = self.c
        return rules._quiet_limits(c.table, c.config.joint_discontinuity_scale)

    def _fused(self, h: CartesianHistory, T_cand, twist, q, differences) -> tuple:
        """The derivatives (pose_derivatives or _twist_derivatives), the joint side
        (joint_side into ``differences``) and rules._quiet's screen in one kernel call, for
        a world whose robots all run one generator: (d, twist_stack, quiet). A rotation the
        kernel leaves alone (at or past pi / 2 in a cycle) takes the numpy functions."""
        k, limits = self._kernel, self._screen_limits()
        if self.c.modes.n_cartesian_position:
            stack = self._pose_stack
            quiet = k.pose_step(T_cand, h.T, h.history, stack, q, h.joint, differences, _DT, limits)
            if quiet < 0:
                rules.pose_derivatives(T_cand, h.T, h.history, 1, out=stack)
                rules.joint_side(q, h.q_ik, h.dq_ik, h.ddq_ik, 1, out=differences)
            return rules.PoseDerivatives(stack), None, quiet > 0
        stack = self._twist_stack
        quiet = k.twist_step(twist, h.twist, h.dtwist, stack, q, h.joint, differences, _DT, limits)
        return None, stack, quiet

    def _twist_target(self, T: np.ndarray, twist: np.ndarray) -> np.ndarray:
        """A twist motion's IK target: the previous target ``T`` moved by the twist over
        1 ms (translation in the base frame, rotation composed on the left: base-frame
        omega)."""
        T_tw, p_tw, R_tw = self._T_twist
        if self._kernel is not None:
            # In one call: the translation the same bits, the rotation to rounding (its
            # 3x3 products; numpy's go through BLAS).
            self._kernel.twist_target(T, twist, T_tw)
            return T_tw
        T_tw[...] = T
        p_tw += twist[:, :3] * _DT
        if count_nonzero(twist[:, 3:]):  # (a zero rotation leaves R exactly as it is)
            np.matmul(rotation_exp(twist[:, 3:] * _DT), T[:, :3, :3], out=R_tw)
        return T_tw

    def _twist_derivatives(self, h: CartesianHistory, twist: np.ndarray) -> np.ndarray:
        """(n, 3, 6) [twist, dtwist, ddtwist] against the history, side by side as the
        pose's derivatives."""
        stack = self._twist_stack
        dtwist, ddtwist = stack[:, 1], stack[:, 2]
        stack[:, 0] = twist
        np.subtract(twist, h.twist, out=dtwist)
        dtwist /= _DT
        np.subtract(dtwist, h.dtwist, out=ddtwist)
        ddtwist /= _DT
        return stack

    def _joint_checked(
        self, h: CartesianHistory, ik: IkResult, first: np.ndarray, active: np.ndarray
    ) -> np.ndarray:
        """(n,) where the joint side's acceleration is judged (29 / 30); the jerk
        (``self._joint[:, 3]``) is zeroed where its history is not warm yet."""
        n = self.c.n
        if count_nonzero(ik.converged) == n and not count_nonzero(first):
            # Every solve converged, none opens its motion (the common case): judged as
            # far as each history is warm; a warm jerk implies a warm acceleration.
            ik_jerk = h.ik_warm >= _WARM_JERK
            if count_nonzero(ik_jerk) == n:
                return ik.converged
            self._joint[~ik_jerk, 3] = 0.0
            return h.ik_warm >= _WARM_ACCELERATION
        warm = ik.converged & ~first
        failed = active & ~ik.converged
        if count_nonzero(failed):
            self._log_ik_failure(failed, ik)
        ik_jerk = warm & (h.ik_warm >= _WARM_JERK)
        self._joint[~ik_jerk, 3] = 0.0
        return warm & (h.ik_warm >= _WARM_ACCELERATION)

    def _elbow(
        self, h: CartesianHistory, candidates: Candidates, have: np.ndarray, extrapolate
    ) -> tuple[rules.ElbowStream, np.ndarray]:
        """The elbow stream: the commanded one where valid, extrapolated while one is
        streamed; and elbow[0]'s extrapolated velocity."""
        if not (count_nonzero(candidates.elbow_valid) or count_nonzero(h.has_elbow)):
            # No elbow commanded nor streamed (the common case): nothing to difference.
            stream = rules.ElbowStream(
                h.elbow, self._none, h.has_elbow, h.elbow[:, 1], self._no_elbow
            )
            return stream, h.de
        n = self.c.n
        e_new = have & candidates.elbow_valid
        e_keep = extrapolate & h.has_elbow
        if count_nonzero(e_keep):
            e_ex, de_ex = extrapolation.elbow_step(h.elbow, h.de, h.dde_frozen, _DT)
        else:
            e_ex, de_ex = h.elbow, h.de
        if count_nonzero(e_new) or count_nonzero(e_keep):
            elbow = np.where(
                e_new[:, None], candidates.elbow, np.where(e_keep[:, None], e_ex, h.elbow)
            )
        else:
            elbow = h.elbow
        has_elbow = e_new | e_keep
        # The elbow's history matters only while some robot streams (or streamed) one.
        if count_nonzero(has_elbow) or count_nonzero(h.has_elbow):
            de = rules.elbow_derivatives(elbow[:, 0], h.elbow[:, 0], h.de, h.dde, 1)
        else:  # unread: row 17 needs an elbow, the history is kept only while one streams
            de = rules.ElbowDerivatives(*(np.zeros(n),) * 3)
        stream = rules.ElbowStream(elbow, has_elbow, h.has_elbow, h.elbow[:, 1], de)
        return stream, de_ex

    def _check(self, step: _Step, first: np.ndarray, active: np.ndarray) -> None:
        """Judge ``active``'s step by its generator's precedence table: logged, enforced."""
        c, m = self.c, self.c.modes
        n = c.n
        if m.n_cartesian_position:
            # The kernel's screen is check_cartesian_pose's own shortcut; it runs only when
            # every robot runs this generator, so there is no twist table to judge either.
            if step.quiet and not (count_nonzero(first) or count_nonzero(step.elbow.has)):
                return
            judged_pose = active if m.n_cartesian_position == n else active & m.cartesian_position
            if count_nonzero(judged_pose):
                self._check_pose(step, first, judged_pose)
        if not m.n_cartesian_velocity:
            return
        judged_twist = active if m.n_cartesian_velocity == n else active & m.cartesian_velocity
        if step.quiet and not count_nonzero(step.elbow.has):
            return  # the kernel's screen: check_cartesian_velocity's own shortcut
        if count_nonzero(judged_twist):
            table, scale = c.table, c.config.joint_discontinuity_scale
            check = rules.check_cartesian_velocity(
                step.twist_stack, first, step.elbow, step.joint, table, scale
            )
            if check.tripped is None:  # nothing tripped (the common case)
                return

            def twist_quantities() -> dict:  # built only for a log line
                twist, dtwist, ddtwist = (step.twist_stack[:, k] for k in range(3))
                joint, elbow = step.joint, step.elbow
                return {
                    "acceleration": [
                        ("O_dP_EE_c", _norm3(dtwist[:, :3]), table.a_trans_max, "m/s^2"),
                        ("O_dP_EE_c rotation", _norm3(dtwist[:, 3:]), table.a_rot_max, "rad/s^2"),
                    ],
                    "jerk": [
                        ("O_dP_EE_c", _norm3(ddtwist[:, :3]), table.j_trans_max, "m/s^3"),
                        ("O_dP_EE_c rotation", _norm3(ddtwist[:, 3:]), table.j_rot_max, "rad/s^3"),
                    ],
                    "velocity": [
                        ("O_dP_EE_c", _norm3(twist[:, :3]), table.v_trans_max, "m/s"),
                        ("O_dP_EE_c rotation", _norm3(twist[:, 3:]), table.v_rot_max, "rad/s"),
                    ],
                    "IK joint acceleration": [
                        ("IK(O_dP_EE_c)", joint.ddq, table.ik_ddq_max * scale, "rad/s^2"),
                        ("IK(O_dP_EE_c)", joint.dddq, table.ik_dddq_max * scale, "rad/s^3"),
                    ],
                    "elbow sign": ("elbow_c[1]", elbow.command[:, 1], elbow.prev_flag, ""),
                    "elbow": _elbow_quantities(elbow.command, elbow.derivatives, table),
                }

            self._judge(check, judged_twist, rules.TWIST_ROWS, twist_quantities, None)

    def _check_pose(self, step: _Step, first: np.ndarray, rows: np.ndarray) -> None:
        """The O_T_EE_c table (16, 22, 21, 19, 18, 20, 29, 30, 17) over ``rows``."""
        c, w, cfg = self.c, self.c.writer, self.c.config
        table, scale = c.table, cfg.joint_discontinuity_scale
        d, T_cand, elbow, joint = step.d, step.T, step.elbow, step.joint
        check = rules.check_cartesian_pose(
            d,
            first,
            T_cand,
            w.O_T_EE,
            elbow,
            w.elbow,
            joint,
            table,
            scale,
            cfg.cartesian_start_translation_tolerance,
            cfg.cartesian_start_rotation_tolerance,
            cfg.start_elbow_tolerance,
        )
        if check.tripped is None:  # nothing tripped (the common case)
            return

        def pose_quantities() -> dict:  # built only for a log line
            return {
                "start pose": (
                    "O_T_EE_c - O_T_EE (translation)",
                    _norm_rows(T_cand, w),
                    cfg.cartesian_start_translation_tolerance,
                    "m",
                ),
                "start elbow": (
                    "elbow_c[0] - q[2]",
                    elbow.command[:, 0] - w.elbow[:, 0],
                    cfg.start_elbow_tolerance,
                    "rad",
                ),
                "elbow sign": ("elbow_c[1]", elbow.command[:, 1], elbow.prev_flag, ""),
                "acceleration": [
                    ("O_T_EE_c", _norm3(d.a), table.a_trans_max, "m/s^2"),
                    ("O_T_EE_c rotation", _norm3(d.alpha), table.a_rot_max, "rad/s^2"),
                ],
                "velocity": [
                    ("O_T_EE_c", _norm3(d.v), table.v_trans_max, "m/s"),
                    ("O_T_EE_c rotation", _norm3(d.omega), table.v_rot_max, "rad/s"),
                ],
                "jerk": [
                    ("O_T_EE_c", _norm3(d.jerk), table.j_trans_max, "m/s^3"),
                    ("O_T_EE_c rotation", _norm3(d.zeta), table.j_rot_max, "rad/s^3"),
                ],
                "IK joint acceleration": (
                    "IK(O_T_EE_c)",
                    joint.ddq,
                    table.ik_ddq_max * scale,
                    "rad/s^2",
                ),
                "IK joint jerk": (
                    "IK(O_T_EE_c)",
                    joint.dddq,
                    table.ik_dddq_max * scale,
                    "rad/s^3",
                ),
                "elbow": _elbow_quantities(elbow.command, elbow.derivatives, table),
            }

        self._judge(check, rows, rules.POSE_ROWS, pose_quantities, rules.POSE_IK_ROW)

    def _record(
        self,
        step: _Step,
        real: np.ndarray,
        apply: np.ndarray,
        extrapolate: np.ndarray,
        first: np.ndarray,
    ) -> None:
        """Record what survived the checks (``apply``; ``real``: the commands that arrived)."""
        c, m, h = self.c, self.c.modes, self.reference
        n = c.n
        d = step.d
        every = count_nonzero(apply) == n  # (the common case: plain copies)
        every_real = every and count_nonzero(real) == n
        any_lost = step.pose_ex is not None
        any_first = count_nonzero(first) > 0
        x = extrapolate[:, None] if any_lost else None
        if (
            self._kernel is not None
            and every_real
            and not (any_lost or any_first)
            and self._record_plain(step)
        ):
            self._record_elbow(step, real, apply, extrapolate)
            self._record_joint_side(step, apply, first, True)
            return
        put_rows(h.T, step.T, apply, every)
        if d is not None:
            if any_lost or any_first:
                a = apply[:, None]
                at_rest = (first & apply)[:, None]
                v, omega, acc, alpha = d.v, d.omega, d.a, d.alpha
                if any_lost:
                    v_ex, w_ex = step.pose_ex
                    v, omega = np.where(x, v_ex, v), np.where(x, w_ex, omega)
                    acc = np.where(x, h.a_frozen, acc)
                    alpha = np.where(x, h.alpha_frozen, alpha)
                if count_nonzero(first):
                    zero3 = np.zeros((n, 3))
                    v, omega = np.where(at_rest, zero3, v), np.where(at_rest, zero3, omega)
                    acc, alpha = np.where(at_rest, zero3, acc), np.where(at_rest, zero3, alpha)
                np.copyto(h.v, v, where=a)
                np.copyto(h.omega, omega, where=a)
                np.copyto(h.a, acc, where=a)
                np.copyto(h.alpha, alpha, where=a)
            else:  # every value a real difference: the history's two orders in one copy
                put_rows(h.history, d.stacked[:, :2], apply, every)
            put_rows(h.acceleration_frozen, h.history[:, 1], real, every_real)
        if m.n_cartesian_velocity:
            put_rows(h.twist, step.twist, apply, every)
            dtwist = step.twist_stack[:, 1]
            if any_lost:
                dtwist = np.where(x, h.dtwist_frozen, dtwist)
            put_rows(h.dtwist, dtwist, apply, every)
            put_rows(h.dtwist_frozen, h.dtwist, real, every_real)
        self._record_reported(apply, first, every and not any_first)
        self._record_elbow(step, real, apply, extrapolate)
        self._record_joint_side(step, apply, first, every and not any_first)

    def _record_plain(self, step: _Step) -> bool:
        """_record's copies and _record_reported in one kernel call, when every robot
        recorded a command that arrived, none opens its motion and all run one generator
        (the common case; the same values as the numpy path); False otherwise."""
        m, h, n = self.c.modes, self.reference, self.c.n
        if m.n_cartesian_position == n:
            self._kernel.record_pose(
                step.T, step.d.stacked, h.T, h.history, h.acceleration_frozen, h.reported,
                h.dreported,
            )  # fmt: skip
            return True
        if m.n_cartesian_velocity == n:
            self._kernel.record_twist(
                step.T, step.twist, step.twist_stack, h.T, h.twist, h.dtwist, h.dtwist_frozen,
                h.reported, h.dreported,
            )  # fmt: skip
            return True
        return False

    def _record_reported(self, apply: np.ndarray, first: np.ndarray, plain: bool) -> None:
        """What the state reports as the commanded twist and its rate. A twist motion: its
        own twist. A pose motion: the commanded pose's twist in the base frame, rotation as
        log(R_c R_prev^T) = R_c omega_body — what libfranka's pose limiter computes and
        then reads back from O_dP_EE_c / O_ddP_EE_c as the last commanded twist and
        acceleration (src/control_loop.cpp, ControlLoop<CartesianPose>::convertMotion)."""
        c, m, h = self.c, self.c.modes, self.reference
        if m.n_cartesian_position:
            spatial = self._spatial
            spatial[:, :3] = h.v
            einsum("nij,nj->ni", h.T[:, :3, :3], h.omega, out=spatial[:, 3:])
            reported = (
                spatial
                if m.n_cartesian_position == c.n
                else (np.where(m.cartesian_position[:, None], spatial, h.twist))
            )
        else:
            reported = h.twist
        if plain:  # every robot recorded, none at rest: the rate in place, then the twist
            np.subtract(reported, h.reported, out=h.dreported)
            h.dreported /= _DT
            h.reported[...] = reported
            return
        a = apply[:, None]
        dreported = (reported - h.reported) / _DT
        if count_nonzero(first):
            dreported = np.where((first & apply)[:, None], 0.0, dreported)
        np.copyto(h.dreported, dreported, where=a)
        np.copyto(h.reported, reported, where=a)

    def _record_elbow(
        self, step: _Step, real: np.ndarray, apply: np.ndarray, extrapolate: np.ndarray
    ) -> None:
        """The elbow's history (the 1-D law's derivatives), kept only while one is streamed."""
        h, elbow = self.reference, step.elbow
        if not (count_nonzero(elbow.has) or count_nonzero(h.has_elbow)):
            return  # none streamed, now or before (the common case, without the mask)
        streamed = apply & elbow.has
        if not (count_nonzero(streamed) or count_nonzero(h.has_elbow)):
            return
        de = elbow.derivatives
        np.copyto(h.de, np.where(extrapolate, step.de_ex, de.v), where=streamed)
        np.copyto(h.dde, np.where(extrapolate, h.dde_frozen, de.a), where=streamed)
        fresh_elbow = streamed & ~h.has_elbow
        h.de[fresh_elbow] = h.dde[fresh_elbow] = 0.0
        np.copyto(h.dde_frozen, h.dde, where=real)
        np.copyto(h.elbow, elbow.command, where=streamed[:, None])
        h.set_has_elbow(np.where(apply, elbow.has, h.has_elbow))

    def _record_joint_side(
        self, step: _Step, apply: np.ndarray, first: np.ndarray, plain: bool
    ) -> None:
        """The joint history: rebased at rest on the opening command and after a failure.
        ``plain``: every robot records, none opens its motion."""
        h, ik = self.reference, step.ik
        a = apply[:, None]
        if count_nonzero(ik.converged) == self.c.n and not count_nonzero(first):
            # Every solve converged and none opens its motion (the common case): nothing
            # is rebased, every applied solution is usable; q, dq, ddq in one copy.
            if plain:
                h.joint[...] = step.solution
                h.ik_warm += 1.0
            else:
                np.copyto(h.joint, step.solution, where=a[:, :, None])
                np.add(h.ik_warm, 1.0, out=h.ik_warm, where=apply)
            return
        rebase = apply & (first | ~ik.converged)
        np.copyto(h.q_ik, ik.q, where=(apply & _usable(ik))[:, None])
        np.copyto(h.dq_ik, np.where(rebase[:, None], 0.0, step.dq), where=a)
        np.copyto(h.ddq_ik, np.where(rebase[:, None], 0.0, step.joint.ddq), where=a)
        # The opening command starts the history at rest, which is true: the joint side is
        # judged from the next command on. A failed solve leaves no valid history: the
        # acceleration needs two more solutions, the jerk three.
        warm_after = np.where(first, _WARM_JERK, np.where(rebase, 0, h.ik_warm + 1))
        np.copyto(h.ik_warm, warm_after, where=apply)

    # -- late datagrams ------------------------------------------------------------------------

    def late_datagrams(self, commands: np.ndarray, late: np.ndarray, ids: np.ndarray) -> None:
        """Seed "A datagram that turns up late replaces the guess it stood in for".

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
        if count_nonzero(rewind):
            self._rewind(commands, rewind, ids)
        judged = late & ~rewind & self.c.modes.cartesian
        if count_nonzero(judged):
            self._judge_late(commands, judged, ids)

    def _late_candidates(self, commands: np.ndarray, rows: np.ndarray) -> Candidates:
        """The Cartesian fields of late datagrams as candidates (the cycle's own untouched)."""
        m = self.c.modes
        T = self.T_cmd.copy()
        pose = rows & m.cartesian_position
        if count_nonzero(pose):
            np.copyto(T, from_wire(commands["O_T_EE_c"]), where=pose[:, None, None])
        r = rows[:, None]
        twist = np.where(r, commands["O_dP_EE_c"], self.twist_cmd)
        elbow = np.where(r, commands["elbow_c"], self.elbow_cmd)
        return Candidates(T, twist, elbow, rows & commands["valid_elbow"].astype(bool))

    def _rewind(self, commands: np.ndarray, rows: np.ndarray, ids: np.ndarray) -> None:
        """The datagram a run is missing replaces the guess it stood in for (see above)."""
        c = self.c
        self.reference.rewind(rows)
        self._cycle(rows, self._none, self._late_candidates(commands, rows), ids)
        # The sample stands for state id + 1; the history must stand for the last
        # published state: guess the cycles in between again, from the real sample
        # (a later datagram of the backlog rewinds them in turn).
        behind = c.writer.message_id.astype(np.int64) - ids.astype(np.int64) - 1
        behind = np.where(rows, behind, 0)
        for j in range(int(behind.max())):
            again = rows & (behind > j) & c.modes.cartesian
            if not count_nonzero(again):
                break
            self._cycle(self._none, again, self._cycle_candidates, ids)

    def _judge_late(self, commands: np.ndarray, rows: np.ndarray, ids: np.ndarray) -> None:
        """Judge late datagrams of ``rows`` without recording them: each against the history
        published in the state it answers (older than the ring: the history as it stands),
        over one cycle; applied to the servo this cycle (seed: "within a cycle a late
        command is the freshest intent there is")."""
        current = self.c.writer.message_id
        h = self.reference.published(np.where(rows, ids, current), int(current[0]))
        step = self._evaluate(
            h, self._late_candidates(commands, rows), rows, self._none, self._none, rows
        )
        self._check(step, self._none, rows)
        ik = step.ik
        apply = rows & self.c.modes.cartesian & _usable(ik)
        if count_nonzero(apply):
            dq = np.where(ik.converged[:, None], step.dq, 0.0)
            self.engine.apply_late(apply, ik.q, dq)

    def _judge(self, check, rows, names, quantities, ik_row) -> None:
        """Name each violation's row for the log; 29 brings 30 when one command breaks both."""
        error = check.error
        if not count_nonzero(rows & (error >= 0)):
            return

        def describe(i: int):
            k = int(np.argmax(check.tripped[i]))
            return rules.describe_cartesian(i, int(error[i]), names[k], quantities())

        extra = None
        if ik_row is not None:
            both = check.tripped[:, ik_row] & check.tripped[:, ik_row + 1]
            both &= error == rules.POSE_CODES[ik_row]
            if count_nonzero(both):
                extra = {
                    i: [int(Error.cartesian_motion_generator_joint_acceleration_discontinuity)]
                    for i in np.flatnonzero(both).tolist()
                }
        self.engine._judge(error, rows, describe, extra)

    def _log_ik_failure(self, failed: np.ndarray, ik) -> None:
        for i in np.flatnonzero(failed & ~self._ik_failed_logged).tolist():
            log.warning(
                "robot %d: the commanded pose has no converged IK solution (residual %.3g m, "
                "%.3g rad): the joint-side checks (29, 30) are skipped",
                i,
                float(ik.position_error[i]),
                float(ik.rotation_error[i]),
            )
            self._ik_failed_logged[i] = True

    # -- what the state reports ----------------------------------------------------------------

    def servo(self, q_ref: np.ndarray, dq_ref: np.ndarray | None):
        """The joint servo's target: the IK solution for robots in a Cartesian motion (a
        late datagram's intent overrides it afterwards: engine.servo_reference)."""
        h, m = self.reference, self.c.modes
        if m.n_cartesian == self.c.n:  # every robot (copies: the history moves on)
            return h.q_ik.copy(), h.dq_ik.copy()
        rows = m.cartesian[:, None]
        dq = np.zeros_like(q_ref) if dq_ref is None else dq_ref
        return np.where(rows, h.q_ik, q_ref), np.where(rows, h.dq_ik, dq)

    def publish(self) -> None:
        """O_T_EE_d / O_T_EE_c, O_dP_EE_d / O_dP_EE_c, elbow_d / elbow_c and q_d of the
        robots in a Cartesian motion (seed "RobotState fields", the three regimes)."""
        c, m, w, h = self.c, self.c.modes, self.c.writer, self.reference
        n = c.n
        if m.n_cartesian_position:
            put_rows(w.O_T_EE_d, to_wire(h.T), m.cartesian_position, m.n_cartesian_position == n)
            put_rows(w.O_T_EE_c, w.O_T_EE_d, m.cartesian_position, m.n_cartesian_position == n)
        if m.n_cartesian_velocity:
            T_start = to_wire(self.start_T)
            put_rows(w.O_T_EE_d, T_start, m.cartesian_velocity, m.n_cartesian_velocity == n)
            put_rows(w.O_T_EE_c, T_start, m.cartesian_velocity, m.n_cartesian_velocity == n)
        every = m.n_cartesian == n
        cartesian = m.cartesian
        put_rows(w.field["O_dP_EE_d"], h.reported, cartesian, every)
        put_rows(w.field["O_dP_EE_c"], h.reported, cartesian, every)
        put_rows(w.field["O_ddP_EE_c"], h.dreported, cartesian, every)
        if count_nonzero(h.has_elbow):
            streamed = (m.cartesian & h.has_elbow)[:, None]
            np.copyto(w.elbow_d, h.elbow, where=streamed)
            np.copyto(w.elbow_c, h.elbow, where=streamed)
        # Seed: "the sim still publishes the measured q there during a Cartesian motion".
        put_rows(w.q_d, c.physics.q, cartesian, every)

    def remember(self, message_id: int) -> None:
        """The history as published in state ``message_id`` (what a late datagram
        answering it is judged against)."""
        self.reference.remember(message_id)

    def end(self, i: int) -> None:
        """The motion ended: the twist echo returns to zero."""
        w, h = self.c.writer, self.reference
        w.field["O_dP_EE_d"][i] = 0.0
        w.field["O_dP_EE_c"][i] = 0.0
        w.field["O_ddP_EE_c"][i] = 0.0
        h.twist[i] = 0.0
        h.reported[i] = h.dreported[i] = 0.0
        h.has_elbow[i] = False
        h.elbow_flag[i] = 0.0


def _usable(ik: IkResult) -> np.ndarray:
    """(n,) the IK solutions the servo may follow: converged, or ended near the target.

    A solve that ended far from the target (an unreachable pose) is not followed: the
    servo holds the last usable solution instead of a diverging iterate into the stops
    (the arm would flail at full torque).
    """
    return ik.converged | (
        (ik.position_error <= USABLE_POSITION_ERROR) & (ik.rotation_error <= USABLE_ROTATION_ERROR)
    )


def _norm3(x: np.ndarray) -> np.ndarray:
    return np.sqrt(einsum("ij,ij->i", x, x))


def _norm_rows(T: np.ndarray, w) -> np.ndarray:
    return _norm3(T[:, :3, 3] - w.O_T_EE[:, 12:15])


def _elbow_quantities(elbow: np.ndarray, de, table) -> list:
    """Row 17's candidates for the log line: range, velocity, acceleration, jerk."""
    return [
        ("elbow_c[0]", elbow[:, 0], table.q_upper[2], "rad"),
        ("elbow_c[0] velocity", de.v, table.v_elbow_max, "rad/s"),
        ("elbow_c[0] acceleration", de.a, table.a_elbow_max, "rad/s^2"),
        ("elbow_c[0] jerk", de.jerk, table.j_elbow_max, "rad/s^3"),
    ]
