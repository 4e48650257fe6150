"""What a judged Cartesian step leaves in the history (fci/cartesian/reference.py).

The commanded (or extrapolated) pose and twist with their derivatives, the twist the
state reports and its rate, the elbow's history while one is streamed, and the IK
joint history — rebased at rest on the opening command and after a failed solve.
"""

from __future__ import annotations

import numpy as np

from ..modes import Modes
from ..rows import put_rows
from ..tables import DELTA_T
from .reference import CartesianReference
from .step import WARM_JERK, Step, usable


class CartesianRecorder:
    """Records judged steps of n robots into their Cartesian history."""

    def __init__(self, modes: Modes, history: CartesianReference) -> None:
        self.modes = modes
        self.history = history
        self.n = history.n
        self._spatial = np.empty((self.n, 6))  # a pose motion's reported twist

    def record(
        self,
        step: Step,
        real: np.ndarray,
        apply: np.ndarray,
        extrapolate: np.ndarray,
        first: np.ndarray,
    ) -> None:
        """Record what survived the checks (``apply``; ``real``: the commands that arrived;
        ``first``: opening commands, which start the history at rest)."""
        m, h = self.modes, self.history
        d = step.d
        every = np.count_nonzero(apply) == self.n  # (the common case: plain copies)
        every_real = every and np.count_nonzero(real) == self.n
        any_lost = step.pose_ex is not None
        any_first = np.count_nonzero(first) > 0
        x = extrapolate[:, None] if any_lost else None
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
                if any_first:
                    v, omega = np.where(at_rest, 0.0, v), np.where(at_rest, 0.0, omega)
                    acc, alpha = np.where(at_rest, 0.0, acc), np.where(at_rest, 0.0, alpha)
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
        self._record_joint_side(step, apply, first)

    def _record_reported(self, apply: np.ndarray, first: np.ndarray, plain: bool) -> None:
        """What the state reports as the commanded twist and its rate. A twist motion: its
        own twist. A pose motion: the commanded pose's twist in the base frame, rotation as
        log(R_c R_prev^T) = R_c omega_body — what libfranka's pose limiter computes and
        then reads back from O_dP_EE_c / O_ddP_EE_c as the last commanded twist and
        acceleration (src/control_loop.cpp, ControlLoop<CartesianPose>::convertMotion).
        ``plain``: every robot records and none opens its motion."""
        m, h = self.modes, self.history
        if m.n_cartesian_position:
            spatial = self._spatial
            spatial[:, :3] = h.v
            np.einsum("nij,nj->ni", h.T[:, :3, :3], h.omega, out=spatial[:, 3:])
            reported = (
                spatial
                if m.n_cartesian_position == self.n
                else np.where(m.cartesian_position[:, None], spatial, h.twist)
            )
        else:
            reported = h.twist
        dreported = (reported - h.reported) / DELTA_T
        if not plain:
            dreported = np.where((first & apply)[:, None], 0.0, dreported)
        put_rows(h.dreported, dreported, apply, plain)
        put_rows(h.reported, reported, apply, plain)

    def _record_elbow(
        self, step: Step, real: np.ndarray, apply: np.ndarray, extrapolate: np.ndarray
    ) -> None:
        """The elbow's history (the 1-D law's derivatives), kept only while one is streamed."""
        h, elbow = self.history, step.elbow
        if not (np.count_nonzero(elbow.has) or np.count_nonzero(h.has_elbow)):
            return  # none streamed, now or before (the common case, without the mask)
        streamed = apply & elbow.has
        if not (np.count_nonzero(streamed) or np.count_nonzero(h.has_elbow)):
            return
        de = elbow.derivatives
        np.copyto(h.de, np.where(extrapolate, step.de_ex, de.v), where=streamed)
        np.copyto(h.dde, np.where(extrapolate, h.dde_frozen, de.a), where=streamed)
        fresh_elbow = streamed & ~h.has_elbow
        h.de[fresh_elbow] = h.dde[fresh_elbow] = 0.0
        np.copyto(h.dde_frozen, h.dde, where=real)
        np.copyto(h.elbow, elbow.command, where=streamed[:, None])
        h.set_has_elbow(np.where(apply, elbow.has, h.has_elbow))

    def _record_joint_side(self, step: Step, apply: np.ndarray, first: np.ndarray) -> None:
        """The joint history: rebased at rest on the opening command and after a failure."""
        h, ik = self.history, step.ik
        a = apply[:, None]
        rebase = apply & (first | ~ik.converged)
        if not np.count_nonzero(rebase) and np.count_nonzero(ik.converged) == self.n:
            # Every solve converged and none opens its motion: every applied solution is
            # usable and nothing is rebased; q, dq, ddq in one copy.
            np.copyto(h.joint, step.solution, where=a[:, :, None])
            np.add(h.ik_warm, 1.0, out=h.ik_warm, where=apply)
            return
        np.copyto(h.q_ik, step.ik.q, where=(apply & usable(ik))[:, None])
        np.copyto(h.dq_ik, np.where(rebase[:, None], 0.0, step.dq), where=a)
        np.copyto(h.ddq_ik, np.where(rebase[:, None], 0.0, step.joint.ddq), where=a)
        # The opening command starts the history at rest, which is true: the joint side is
        # judged from the next command on. A failed solve leaves no valid history: the
        # acceleration needs two more solutions, the jerk three.
        warm_after = np.where(first, WARM_JERK, np.where(rebase, 0, h.ik_warm + 1))
        np.copyto(h.ik_warm, warm_after, where=apply)
