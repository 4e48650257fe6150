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

The history lives here (not in JointReference): q_d keeps reporting the
measured q during a Cartesian motion, as the seed says.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from ..sim.kinematics import (
    USABLE_POSITION_ERROR,
    USABLE_ROTATION_ERROR,
    ArmKinematics,
    rotation_exp,
)
from . import extrapolation
from ._fast import count_nonzero
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


class CartesianGenerators:
    """History, checks and IK of the Cartesian generators of n robots."""

    def __init__(self, engine: MotionLimitEngine) -> None:
        self.engine = engine
        c = engine.c
        self.c = c
        n = c.n
        physics = c.physics
        self.kinematics = ArmKinematics(physics.model, physics.layout)
        #: the commanded (pose motion) or twist-integrated (twist motion) EE pose
        self.T = np.tile(np.eye(4), (n, 1, 1))
        #: the pose's history side by side, (n, 2, 6): [[v | omega], [a | alpha]];
        #: v, omega, a and alpha are its views (one difference per order a cycle)
        self.history = np.zeros((n, 2, 6))
        self.v, self.omega = self.history[:, 0, :3], self.history[:, 0, 3:]
        self.a, self.alpha = self.history[:, 1, :3], self.history[:, 1, 3:]
        #: the acceleration frozen for extrapolation, [a | alpha]; a_frozen, alpha_frozen views
        self.acceleration_frozen = np.zeros((n, 6))
        self.a_frozen = self.acceleration_frozen[:, :3]
        self.alpha_frozen = self.acceleration_frozen[:, 3:]
        #: the commanded twist, its acceleration and the frozen acceleration
        self.twist, self.dtwist, self.dtwist_frozen = (np.zeros((n, 6)) for _ in range(3))
        #: the twist the state reports (O_dP_EE_d / O_dP_EE_c) and its rate (O_ddP_EE_c)
        self.reported, self.dreported = np.zeros((n, 6)), np.zeros((n, 6))
        #: the commanded elbow while one is streamed (has_elbow), its derivatives
        self.elbow = np.zeros((n, 2))
        self.de, self.dde, self.dde_frozen = np.zeros(n), np.zeros(n), np.zeros(n)
        self.has_elbow = np.zeros(n, dtype=bool)
        #: the pose a twist motion started from (O_T_EE_d / O_T_EE_c while it runs)
        self.start_T = np.tile(np.eye(4), (n, 1, 1))
        #: the IK solution history: the joint servo's reference
        self.q_ik, self.dq_ik, self.ddq_ik = np.zeros((n, 7)), np.zeros((n, 7)), np.zeros((n, 7))
        #: converged IK samples since the joint history was last rebased
        self.ik_warm = np.zeros(n, dtype=np.int64)
        #: the IK did not converge (logged once per motion)
        self._ik_failed_logged = np.zeros(n, dtype=bool)
        # The cycle's command candidates (the last datagram applied wins).
        self.T_cmd = np.tile(np.eye(4), (n, 1, 1))
        self.twist_cmd = np.zeros((n, 6))
        self.elbow_cmd = np.zeros((n, 2))
        self.elbow_valid = np.zeros(n, dtype=bool)

    # -- motion lifecycle -------------------------------------------------------------------

    def start(self, i: int) -> None:
        """A Cartesian Move started: the history sits at rest at the measured pose."""
        w = self.c.writer
        T = from_wire(w.O_T_EE[i])
        self.T[i] = T
        self.start_T[i] = T
        for x in (self.v, self.omega, self.a, self.alpha, self.a_frozen, self.alpha_frozen):
            x[i] = 0.0
        for x in (self.twist, self.dtwist, self.dtwist_frozen, self.reported, self.dreported):
            x[i] = 0.0
        self.elbow[i] = w.elbow[i]
        self.de[i] = self.dde[i] = self.dde_frozen[i] = 0.0
        self.has_elbow[i] = False
        self.q_ik[i] = self.c.physics.q[i]
        self.dq_ik[i] = self.ddq_ik[i] = 0.0
        self.ik_warm[i] = 0
        self._ik_failed_logged[i] = False

    def take(self, commands: np.ndarray, accepted: np.ndarray) -> None:
        """Keep the Cartesian fields of the accepted commands as the cycle's candidates."""
        rows = accepted & self.c.modes.cartesian
        if not count_nonzero(rows):
            return
        r = rows[:, None]
        m = self.c.modes
        # Each generator reads its own field only (the other is not looked at).
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
        c, m = self.c, self.c.modes
        rows = started & m.cartesian
        if not count_nonzero(rows):
            return
        have = c._have & rows
        lost = rows & ~have
        extrapolate = lost & (c.accounting.lost_run < MAX_LOST_CYCLES)
        held = lost & ~extrapolate
        active = have | extrapolate
        if count_nonzero(held):
            # Seed "Extrapolation stops at 20": the last extrapolated value holds, at rest.
            self.twist[held] = 0.0
            self.reported[held] = self.dreported[held] = 0.0
            self.dq_ik[held] = 0.0
        if not count_nonzero(active):
            return
        first = c._first & have
        pose = m.cartesian_position
        twist_rows = m.cartesian_velocity
        h = have[:, None]
        x = extrapolate[:, None]
        # -- candidates: the command, or the seed's lost-cycle law ---------------------------
        any_lost = bool(count_nonzero(extrapolate))
        if any_lost:
            T_ex, v_ex, w_ex = extrapolation.pose_step(
                self.T, self.v, self.a_frozen, self.omega, self.alpha_frozen, _DT
            )
            tw_ex = extrapolation.velocity_step(self.twist, self.dtwist_frozen, _DT)
            twist = np.where(h, self.twist_cmd, np.where(x, tw_ex, self.twist))
            T_pose = np.where(h[:, :, None], self.T_cmd, T_ex)
        else:
            twist = self.twist_cmd if m.n_cartesian_velocity else self.twist
            T_pose = self.T_cmd
        if m.n_cartesian_velocity:
            # A twist motion's IK target: the previous target moved by the twist over 1 ms
            # (translation in the base frame, rotation composed on the left: base-frame omega).
            T_tw = self.T.copy()
            T_tw[:, :3, 3] += twist[:, :3] * _DT
            if count_nonzero(twist[:, 3:]):  # (a zero rotation leaves R exactly as it is)
                T_tw[:, :3, :3] = rotation_exp(twist[:, 3:] * _DT) @ self.T[:, :3, :3]
            T_cand = (
                T_tw
                if m.n_cartesian_velocity == c.n
                else np.where(pose[:, None, None], T_pose, T_tw)
            )
        else:
            T_cand = T_pose
        # Elbow: the commanded one where valid; extrapolated while one is streamed.
        e_new = have & self.elbow_valid
        e_keep = extrapolate & self.has_elbow
        if count_nonzero(e_keep):
            e_ex, de_ex = extrapolation.elbow_step(self.elbow, self.de, self.dde_frozen, _DT)
        else:
            e_ex, de_ex = self.elbow, self.de
        if count_nonzero(e_new) or count_nonzero(e_keep):
            elbow = np.where(
                e_new[:, None], self.elbow_cmd, np.where(e_keep[:, None], e_ex, self.elbow)
            )
        else:
            elbow = self.elbow
        has_elbow = e_new | e_keep
        # The elbow's history matters only while some robot streams (or streamed) one.
        elbow_in_use = bool(count_nonzero(has_elbow) or count_nonzero(self.has_elbow))
        # -- derivatives ----------------------------------------------------------------------
        # The pose's derivatives judge pose motions (and feed their extrapolation and
        # reported twist); the twist's judge twist motions. Each only when one runs.
        d = (
            rules.pose_derivatives(T_cand, self.T, self.history, 1)
            if m.n_cartesian_position
            else None
        )
        if m.n_cartesian_velocity:
            # Side by side, (n, 3, 6): [twist, dtwist, ddtwist], as the pose's derivatives.
            twist_stack = np.empty((c.n, 3, 6))
            dtwist, ddtwist = twist_stack[:, 1], twist_stack[:, 2]
            twist_stack[:, 0] = twist
            np.subtract(twist, self.twist, out=dtwist)
            dtwist /= _DT
            np.subtract(dtwist, self.dtwist, out=ddtwist)
            ddtwist /= _DT
        if elbow_in_use:
            de = rules.elbow_derivatives(elbow[:, 0], self.elbow[:, 0], self.de, self.dde, 1)
        else:  # unread: row 17 needs an elbow, the history is kept only while one streams
            de = rules.ElbowDerivatives(*(np.zeros(c.n),) * 3)
        # -- the joint side: IK from the previous solution -----------------------------------
        F_T_EE = c.writer.F_T_EE if c.writer._any_custom_ee else None
        e_fixed = np.where(has_elbow, elbow[:, 0], np.nan) if elbow_in_use else None
        ik = self.kinematics.solve(T_cand, self.q_ik, F_T_EE, e_fixed, rows=active)
        dq, ddq, dddq = rules.joint_side(ik.q, self.q_ik, self.dq_ik, self.ddq_ik, 1)
        warm = ik.converged & ~first
        failed = active & ~ik.converged
        if count_nonzero(failed):
            self._log_ik_failure(failed, ik)
        table, scale = c.table, c.config.joint_discontinuity_scale
        ik_acc = warm & (self.ik_warm >= _WARM_ACCELERATION)
        ik_jerk = warm & (self.ik_warm >= _WARM_JERK)
        dddq_checked = np.where(ik_jerk[:, None], dddq, 0.0)
        w = c.writer
        cfg = c.config
        elbow_stream = rules.ElbowStream(elbow, has_elbow, self.has_elbow, self.elbow[:, 1], de)
        joint = rules.JointSide(ddq, dddq_checked, ik_acc)
        judged_pose = active & pose
        if count_nonzero(judged_pose):
            check = rules.check_cartesian_pose(
                d,
                first,
                T_cand,
                w.O_T_EE,
                elbow_stream,
                w.elbow,
                joint,
                table,
                scale,
                cfg.cartesian_start_translation_tolerance,
                cfg.cartesian_start_rotation_tolerance,
                cfg.start_elbow_tolerance,
            )

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
                        elbow[:, 0] - w.elbow[:, 0],
                        cfg.start_elbow_tolerance,
                        "rad",
                    ),
                    "elbow sign": ("elbow_c[1]", elbow[:, 1], self.elbow[:, 1], ""),
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
                        ddq,
                        table.ik_ddq_max * scale,
                        "rad/s^2",
                    ),
                    "IK joint jerk": (
                        "IK(O_T_EE_c)",
                        dddq_checked,
                        table.ik_dddq_max * scale,
                        "rad/s^3",
                    ),
                    "elbow": _elbow_quantities(elbow, de, table),
                }

            self._judge(check, judged_pose, rules.POSE_ROWS, pose_quantities, rules.POSE_IK_ROW)
        judged_twist = active & twist_rows
        if count_nonzero(judged_twist):
            check = rules.check_cartesian_velocity(
                twist_stack, first, elbow_stream, joint, table, scale
            )

            def twist_quantities() -> dict:  # built only for a log line
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
                        ("IK(O_dP_EE_c)", ddq, table.ik_ddq_max * scale, "rad/s^2"),
                        ("IK(O_dP_EE_c)", dddq_checked, table.ik_dddq_max * scale, "rad/s^3"),
                    ],
                    "elbow sign": ("elbow_c[1]", elbow[:, 1], self.elbow[:, 1], ""),
                    "elbow": _elbow_quantities(elbow, de, table),
                }

            self._judge(check, judged_twist, rules.TWIST_ROWS, twist_quantities, None)
        # -- record what survived ----------------------------------------------------------
        apply = active & m.cartesian  # robots aborted above are no longer in a Cartesian motion
        if not count_nonzero(apply):
            return
        real = have & apply
        a = apply[:, None]
        at_rest = (first & apply)[:, None]
        np.copyto(self.T, T_cand, where=a[:, :, None])
        r3 = real[:, None]
        if d is not None:
            if any_lost or count_nonzero(first):
                v, omega, acc, alpha = d.v, d.omega, d.a, d.alpha
                if any_lost:
                    v, omega = np.where(x, v_ex, v), np.where(x, w_ex, omega)
                    acc = np.where(x, self.a_frozen, acc)
                    alpha = np.where(x, self.alpha_frozen, alpha)
                if count_nonzero(first):
                    zero3 = np.zeros((c.n, 3))
                    v, omega = np.where(at_rest, zero3, v), np.where(at_rest, zero3, omega)
                    acc, alpha = np.where(at_rest, zero3, acc), np.where(at_rest, zero3, alpha)
                np.copyto(self.v, v, where=a)
                np.copyto(self.omega, omega, where=a)
                np.copyto(self.a, acc, where=a)
                np.copyto(self.alpha, alpha, where=a)
            else:  # every value a real difference: the history's two orders in one copy
                np.copyto(self.history, d.stacked[:, :2], where=a[:, :, None])
            np.copyto(self.acceleration_frozen, self.history[:, 1], where=r3)
        if m.n_cartesian_velocity:
            np.copyto(self.twist, twist, where=a)
            if any_lost:
                dtwist = np.where(x, self.dtwist_frozen, dtwist)
            np.copyto(self.dtwist, dtwist, where=a)
            np.copyto(self.dtwist_frozen, self.dtwist, where=r3)
        # What the state reports as the commanded twist and its rate. A twist motion: its own
        # twist. A pose motion: the commanded pose's twist in the base frame, rotation as
        # log(R_c R_prev^T) = R_c omega_body — what libfranka's pose limiter computes and
        # then reads back from O_dP_EE_c / O_ddP_EE_c as the last commanded twist and
        # acceleration (src/control_loop.cpp, ControlLoop<CartesianPose>::convertMotion).
        if m.n_cartesian_position:
            spatial = np.empty((c.n, 6))
            spatial[:, :3] = self.v
            np.einsum("nij,nj->ni", self.T[:, :3, :3], self.omega, out=spatial[:, 3:])
            reported = (
                spatial
                if m.n_cartesian_position == c.n
                else (np.where(pose[:, None], spatial, self.twist))
            )
        else:
            reported = self.twist
        dreported = (reported - self.reported) / _DT
        if count_nonzero(first):
            dreported = np.where(at_rest, 0.0, dreported)
        np.copyto(self.dreported, dreported, where=a)
        np.copyto(self.reported, reported, where=a)
        # The elbow's history (the 1-D law's derivatives), kept only while one is streamed.
        streamed = apply & has_elbow
        if count_nonzero(streamed) or count_nonzero(self.has_elbow):
            np.copyto(self.de, np.where(extrapolate, de_ex, de.v), where=streamed)
            np.copyto(self.dde, np.where(extrapolate, self.dde_frozen, de.a), where=streamed)
            fresh_elbow = streamed & ~self.has_elbow
            self.de[fresh_elbow] = self.dde[fresh_elbow] = 0.0
            np.copyto(self.dde_frozen, self.dde, where=real)
            np.copyto(self.elbow, elbow, where=streamed[:, None])
            self.has_elbow = np.where(apply, has_elbow, self.has_elbow)
        # The joint history: rebased at rest on the opening command and after a failure.
        rebase = apply & (first | ~ik.converged)
        # The servo's reference: the solution, unless the solve ended far from the target
        # (an unreachable pose): then it holds the last usable one instead of following a
        # diverging iterate into the stops (the arm would flail at full torque).
        usable = ik.converged | (
            (ik.position_error <= USABLE_POSITION_ERROR)
            & (ik.rotation_error <= USABLE_ROTATION_ERROR)
        )
        np.copyto(self.q_ik, ik.q, where=(apply & usable)[:, None])
        np.copyto(self.dq_ik, np.where(rebase[:, None], 0.0, dq), where=a)
        np.copyto(self.ddq_ik, np.where(rebase[:, None], 0.0, ddq), where=a)
        # The opening command starts the history at rest, which is true: the joint side is
        # judged from the next command on. A failed solve leaves no valid history: the
        # acceleration needs two more solutions, the jerk three.
        warm_after = np.where(first, _WARM_JERK, np.where(rebase, 0, self.ik_warm + 1))
        self.ik_warm = np.where(apply, warm_after, self.ik_warm)
        c._first &= ~have

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
        """The joint servo's target: the IK solution for robots in a Cartesian motion."""
        rows = self.c.modes.cartesian[:, None]
        dq = np.zeros_like(q_ref) if dq_ref is None else dq_ref
        return np.where(rows, self.q_ik, q_ref), np.where(rows, self.dq_ik, dq)

    def publish(self) -> None:
        """O_T_EE_d / O_T_EE_c, O_dP_EE_d / O_dP_EE_c, elbow_d / elbow_c and q_d of the
        robots in a Cartesian motion (seed "RobotState fields", the three regimes)."""
        c, m, w = self.c, self.c.modes, self.c.writer
        pose = m.cartesian_position[:, None]
        twist = m.cartesian_velocity[:, None]
        if m.n_cartesian_position:
            np.copyto(w.O_T_EE_d, to_wire(self.T), where=pose)
            np.copyto(w.O_T_EE_c, to_wire(self.T), where=pose)
        if m.n_cartesian_velocity:
            np.copyto(w.O_T_EE_d, to_wire(self.start_T), where=twist)
            np.copyto(w.O_T_EE_c, to_wire(self.start_T), where=twist)
        cartesian = m.cartesian[:, None]
        np.copyto(w.field["O_dP_EE_d"], self.reported, where=cartesian)
        np.copyto(w.field["O_dP_EE_c"], self.reported, where=cartesian)
        np.copyto(w.field["O_ddP_EE_c"], self.dreported, where=cartesian)
        streamed = (m.cartesian & self.has_elbow)[:, None]
        np.copyto(w.elbow_d, self.elbow, where=streamed)
        np.copyto(w.elbow_c, self.elbow, where=streamed)
        # Seed: "the sim still publishes the measured q there during a Cartesian motion".
        np.copyto(w.q_d, c.physics.q, where=m.cartesian[:, None])

    def end(self, i: int) -> None:
        """The motion ended: the twist echo returns to zero."""
        w = self.c.writer
        w.field["O_dP_EE_d"][i] = 0.0
        w.field["O_dP_EE_c"][i] = 0.0
        w.field["O_ddP_EE_c"][i] = 0.0
        self.twist[i] = 0.0
        self.reported[i] = self.dreported[i] = 0.0
        self.has_elbow[i] = False


def _norm3(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", x, x))


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
