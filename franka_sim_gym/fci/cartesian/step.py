"""One Cartesian cycle's candidates, differenced against a history and solved to joint space.

docs/fci-behaviour.md "The difference formulas", "What the sim does with a lost cycle" and "The
joint side of a Cartesian command": the candidate is the command that arrived or the lost-cycle
law's extrapolation; a twist is integrated onto the IK target pose; the pose's (or the twist's)
derivatives and the elbow's are taken over one cycle; the target is solved from the history's IK
solution at F_T_EE (joint 3 held where an elbow is streamed) and the solution's acceleration and
jerk form the joint side, judged only as far as the joint history is warm. The pose's and the
joint side's differences have their one text in C (fci/cartesian/_history.c, over the history's
rows); a twist motion's integration and derivatives and the elbow's are numpy, here.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from ... import native
from ...sim import rotations
from ...sim.arm import ArmPhysics
from ...sim.ik import USABLE_POSITION_ERROR, USABLE_ROTATION_ERROR, IkResult
from ...sim.kinematics import ArmKinematics
from ...sim.rotations import rotation_exp
from .. import extrapolation
from ..limits import cartesian as rules
from ..modes import Modes
from ..state import StateWriter
from ..tables import DELTA_T
from .reference import CartesianHistory, CartesianReference

#: The history's arithmetic (fci/cartesian/_history.c): missing or stale, importing this
#: module fails with the rebuild command.
_C = native.require("fci.cartesian._history", "History", "usable")

log = logging.getLogger("franka_sim_gym.fci")

#: IK samples after a rebase before the joint side is judged: a solution, then its
#: velocity; the acceleration (29) needs two and the jerk (30) three differences.
WARM_ACCELERATION = 1
WARM_JERK = 2


class Candidates(NamedTuple):
    """One command per robot, as a cycle's candidate: O_T_EE_c (row-major), O_dP_EE_c,
    elbow_c and valid_elbow (each generator reads its own field only)."""

    T: np.ndarray
    twist: np.ndarray
    elbow: np.ndarray
    elbow_valid: np.ndarray


class Step(NamedTuple):
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


def history_plan(
    reference: CartesianReference,
    pose_stack: np.ndarray,
    joint_stack: np.ndarray,
    start_T: np.ndarray,
    writer: StateWriter,
) -> _C.History:
    """The history's arithmetic (fci/cartesian/_history.c ``History``) over ``reference``,
    its differences written to ``pose_stack`` (n, 3, 6) and ``joint_stack`` (n, 4, 7; row 0
    the IK solution), what it publishes written to ``writer``'s Cartesian fields (a twist
    motion's pose: ``start_T`` (n, 4, 4)), with the cycle's, the warm-up's, the IK's and the
    rotations' constants."""
    h, w = reference, writer
    columns = (h.T, h.history, h.acceleration_frozen, h.twist, h.dtwist, h.dtwist_frozen)
    columns += (h.reported, h.dreported, h.joint, h.ik_warm, h.elbow, h.elbow_flag)
    published = (start_T, w.O_T_EE_d, w.O_T_EE_c, w.field["O_dP_EE_d"], w.field["O_dP_EE_c"])
    published += (w.field["O_ddP_EE_c"], w.elbow_d, w.elbow_c)
    return _C.History(
        h.buffer, h.real_echo, h.run, pose_stack, joint_stack, published,
        (h.buffer.shape[1], *(h.column(view) for view in columns)),
        (DELTA_T, WARM_ACCELERATION, WARM_JERK, USABLE_POSITION_ERROR, USABLE_ROTATION_ERROR,
         rotations.NEAR_PI, rotations.TURNING_ABOVE, rotations.SERIES_BELOW,
         rotations.SLERP_LINEAR),
    )  # fmt: skip


def usable(ik: IkResult) -> np.ndarray:
    """(n,) the IK solutions the servo may follow: converged, or ended near the target.

    A solve that ended far from the target (an unreachable pose) is not followed: the
    servo holds the last usable solution instead of a diverging iterate into the stops
    (the arm would flail at full torque). (The record applies the same rule in C.)
    """
    out = np.empty(len(ik.converged), dtype=bool)
    return _C.usable(
        ik.converged, ik.position_error, ik.rotation_error, out,
        USABLE_POSITION_ERROR, USABLE_ROTATION_ERROR,
    )  # fmt: skip


class CartesianStepper:
    """Evaluates Cartesian steps of n robots (the scratch arrays of one step and the IK).

    ``plan`` is the history's arithmetic over ``reference`` and this stepper's scratch
    (fci/cartesian/_history.c): the differences here, the record in record.py, what the state
    publishes in generators.py (``start_T``: a twist motion's start pose).
    """

    def __init__(
        self,
        physics: ArmPhysics,
        modes: Modes,
        writer: StateWriter,
        reference: CartesianReference,
        start_T: np.ndarray,
    ) -> None:
        n = physics.n
        self.n = n
        self.modes = modes
        self.writer = writer
        self.kinematics = ArmKinematics(physics.model, physics.layout)
        #: the IK did not converge (logged once per motion)
        self.ik_failed_logged = np.zeros(n, dtype=bool)
        self.none = np.zeros(n, dtype=bool)
        self.none.setflags(write=False)
        # One step's scratch: a step is evaluated, judged and recorded before the next
        # (a late datagram's, a rewind's and the cycle's steps run one after another).
        T_twist = np.empty((n, 4, 4))  # a twist motion's IK target, its position and rotation
        self._T_twist = (T_twist, T_twist[:, :3, 3], T_twist[:, :3, :3])
        self._twist_stack = np.empty((n, 3, 6))  # [twist, dtwist, ddtwist]
        self._pose_stack = np.empty((n, 3, 6))  # the pose's derivatives
        self._joint = S = np.empty((n, 4, 7))  # [q, dq, ddq, dddq] of the IK solution
        # its views: q; [ddq, dddq] (judged); [q, dq, ddq] (recorded); dq
        self._joint_views = (S[:, 0], S[:, 2:], S[:, :3], S[:, 1])
        self._motion = S[:, :2]  # [q, dq]: the range (27) and the envelope (28)
        self._checked = np.zeros(n, dtype=bool)  # where the joint side's rows are judged
        self._d = rules.PoseDerivatives(self._pose_stack)
        self.plan = history_plan(reference, self._pose_stack, S, start_T, writer)
        # The elbow's derivatives while no elbow is streamed (read, never written).
        zeros = np.zeros(n)
        zeros.setflags(write=False)
        self._no_elbow = rules.ElbowDerivatives(zeros, zeros, zeros)

    def evaluate(
        self,
        h: CartesianHistory,
        candidates: Candidates,
        have: np.ndarray,
        extrapolate: np.ndarray,
        first: np.ndarray,
        active: np.ndarray,
    ) -> Step:
        """Difference ``have``'s candidates (and the extrapolation of ``extrapolate``)
        against the history ``h`` and solve them from its IK solution (over one cycle)."""
        m, n = self.modes, self.n
        n_twist = m.n_cartesian_velocity
        # -- candidates: the command, or the lost-cycle law (docs/fci-behaviour.md) ----------------
        pose_ex = None
        if np.count_nonzero(extrapolate):
            hv = have[:, None]
            x = extrapolate[:, None]
            T_ex, v_ex, w_ex = extrapolation.pose_step(
                h.T, h.v, h.a_frozen, h.omega, h.alpha_frozen, DELTA_T
            )
            pose_ex = (v_ex, w_ex)
            tw_ex = extrapolation.velocity_step(h.twist, h.dtwist_frozen, DELTA_T)
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
        # -- derivatives: the pose's judge pose motions (and feed their extrapolation and
        # reported twist), the twist's judge twist motions; each only when one runs.
        d = None
        if m.n_cartesian_position:
            self.plan.pose_derivatives(h.buffer, T_cand)
            d = self._d
        twist_stack = self._twist_derivatives(h, twist) if n_twist else None
        # -- the joint side: IK from the previous solution -----------------------------------
        streamed = elbow.has is not self.none and bool(
            np.count_nonzero(elbow.has) or np.count_nonzero(elbow.had)
        )
        e_fixed = np.where(elbow.has, elbow.command[:, 0], np.nan) if streamed else None
        q, judged, recorded, dq = self._joint_views
        F_T_EE = self.writer.F_T_EE if self.writer.any_custom_ee else None
        ik = self.kinematics.solve(T_cand, h.q_ik, F_T_EE, e_fixed, rows=active, out=q)
        checked = self._checked
        if self.plan.joint_side(h.buffer, first, active, ik.converged, checked):
            self._log_ik_failure(active & ~ik.converged, ik)
        joint = rules.JointSide(judged, checked, self._motion, h.q_ik, active & ik.converged)
        return Step(T_cand, twist, twist_stack, d, pose_ex, elbow, de_ex, ik, dq, joint, recorded)

    def _twist_target(self, T: np.ndarray, twist: np.ndarray) -> np.ndarray:
        """A twist motion's IK target: the previous target ``T`` moved by the twist over
        1 ms (translation in the base frame, rotation composed on the left: base-frame
        omega)."""
        T_tw, p_tw, R_tw = self._T_twist
        T_tw[...] = T
        p_tw += twist[:, :3] * DELTA_T
        if np.count_nonzero(twist[:, 3:]):  # (a zero rotation leaves R exactly as it is)
            np.matmul(rotation_exp(twist[:, 3:] * DELTA_T), T[:, :3, :3], out=R_tw)
        return T_tw

    def _twist_derivatives(self, h: CartesianHistory, twist: np.ndarray) -> np.ndarray:
        """(n, 3, 6) [twist, dtwist, ddtwist] against the history, side by side as the
        pose's derivatives."""
        stack = self._twist_stack
        dtwist, ddtwist = stack[:, 1], stack[:, 2]
        stack[:, 0] = twist
        np.subtract(twist, h.twist, out=dtwist)
        dtwist /= DELTA_T
        np.subtract(dtwist, h.dtwist, out=ddtwist)
        ddtwist /= DELTA_T
        return stack

    def _elbow(
        self, h: CartesianHistory, candidates: Candidates, have: np.ndarray, extrapolate
    ) -> tuple[rules.ElbowStream, np.ndarray]:
        """The elbow stream: the commanded one where valid, extrapolated while one is
        streamed; and elbow[0]'s extrapolated velocity."""
        if not (np.count_nonzero(candidates.elbow_valid) or np.count_nonzero(h.has_elbow)):
            # No elbow commanded nor streamed (the common case): nothing to difference.
            stream = rules.ElbowStream(
                h.elbow, self.none, h.has_elbow, h.elbow[:, 1], self._no_elbow
            )
            return stream, h.de
        e_new = have & candidates.elbow_valid
        e_keep = extrapolate & h.has_elbow
        if np.count_nonzero(e_keep):
            e_ex, de_ex = extrapolation.elbow_step(h.elbow, h.de, h.dde_frozen, DELTA_T)
        else:
            e_ex, de_ex = h.elbow, h.de
        elbow = np.where(e_new[:, None], candidates.elbow, np.where(e_keep[:, None], e_ex, h.elbow))
        has_elbow = e_new | e_keep
        de = rules.elbow_derivatives(elbow[:, 0], h.elbow[:, 0], h.de, h.dde, 1)
        stream = rules.ElbowStream(elbow, has_elbow, h.has_elbow, h.elbow[:, 1], de)
        return stream, de_ex

    def _log_ik_failure(self, failed: np.ndarray, ik: IkResult) -> None:
        for i in np.flatnonzero(failed & ~self.ik_failed_logged).tolist():
            log.warning(
                "robot %d: the commanded pose has no converged IK solution (residual %.3g m, "
                "%.3g rad): the joint-side checks (29, 30) are skipped",
                i,
                float(ik.position_error[i]),
                float(ik.rotation_error[i]),
            )
            self.ik_failed_logged[i] = True
