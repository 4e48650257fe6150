"""What a judged Cartesian step leaves in the history (fci/cartesian/reference.py).

The commanded (or extrapolated) pose and twist with their derivatives, the twist the
state reports and its rate, the elbow's history while one is streamed, and the IK
joint history — rebased at rest on the opening command and after a failed solve. All
but the elbow's are one C call (fci/cartesian/_history.c ``History.record``):

* the pose and its history, while a pose motion runs: the differences; an extrapolated
  cycle's own velocity and the frozen acceleration (docs/fci-behaviour.md "What the sim
  does with a lost cycle"); at rest on the opening command; the frozen acceleration
  follows the commands that arrived;
* the twist, its acceleration (frozen for an extrapolated cycle) and the frozen one,
  while a twist motion runs;
* the reported twist and its rate (zero on the opening command). A twist motion: its own
  twist. A pose motion: the commanded pose's twist in the base frame, rotation as
  log(R_c R_prev^T) = R_c omega_body — what libfranka's pose limiter computes and then
  reads back from O_dP_EE_c / O_ddP_EE_c as the last commanded twist and acceleration
  (src/control_loop.cpp, ControlLoop<CartesianPose>::convertMotion);
* the IK joint history: a usable solution (step.py ``usable``) is followed; the opening
  command starts the history at rest, which is true: the joint side is judged from the
  next command on; a failed solve leaves no valid history: the acceleration needs two
  more solutions, the jerk three (step.py ``WARM_*``);
* the last real command's echo, and no guesses since, for the commands that arrived.
"""

from __future__ import annotations

import numpy as np

from ..modes import Modes
from .reference import CartesianReference
from .step import _C, Step


class CartesianRecorder:
    """Records judged steps of n robots into their Cartesian history (``plan``: the
    stepper's, fci/cartesian/_history.c)."""

    def __init__(self, modes: Modes, history: CartesianReference, plan: _C.History) -> None:
        self.modes = modes
        self.history = history
        self.n = history.n
        self._plan = plan

    def record(
        self,
        step: Step,
        real: np.ndarray,
        apply: np.ndarray,
        extrapolate: np.ndarray,
        first: np.ndarray,
        echo: np.ndarray,
    ) -> None:
        """Record what survived the checks (``apply``; ``real``: the commands that arrived,
        echoing ``echo``; ``first``: opening commands, which start the history at rest)."""
        ik = step.ik
        v_ex, w_ex = (None, None) if step.pose_ex is None else step.pose_ex
        self._plan.record(
            step.T, step.twist, step.twist_stack, v_ex, w_ex, self.modes.cartesian_position,
            apply, real, extrapolate, first, ik.converged, ik.position_error, ik.rotation_error,
            echo,
        )  # fmt: skip
        self._record_elbow(step, real, apply, extrapolate)

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
