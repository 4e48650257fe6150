"""The arms' rigid-body model at the measured state: what a model-based estimator needs.

The FR3 estimates the external torque from its dynamic model and its joint torque
sensors; the model terms are those of the arm as simulated (the URDF's inertials, the
mounted hand as a rigid end effector), evaluated at the state MuJoCo just reached.
Contact forces are *not* read here: they reach an estimate only through the motion
and the measured torques they cause, as on the robot. The external-force estimator
itself is the controller's (fci/contact/estimate.py); this is the backend it reads.

Everything is (n, 7) per arm, in the arm's base frame (bases are not rotated).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .. import native
from .views import ArmRows

if TYPE_CHECKING:
    from .arm import ArmPhysics


#: The one text of :func:`jacobian_at` (sim/_dynamics.c; issue 38: no numpy twin).
_DYNAMICS = native.require("sim._dynamics", "jacobian_at")


def jacobian_at(
    axes: np.ndarray, anchors: np.ndarray, point: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """(n, 6, 7) geometric Jacobian of ``point`` (n, 3) on the last link: rows v, omega.

    Revolute joints only: column j is [z_j x (p - o_j); z_j] with z_j the joint's unit
    axis and o_j a point of it (``axes``, ``anchors``: (n, 7, 3), in the frame of
    ``point``). Its only text is C (sim/_dynamics.c).
    """
    if out is None:
        out = np.empty((len(point), 6, 7))
    return _DYNAMICS.jacobian_at(axes, anchors, point, out)


def weight_torque(jacobian: np.ndarray, mass: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """(n, 7) the joint torques that hold masses ``mass`` (n,) against ``gravity`` (3,)
    at the points whose Jacobians are ``jacobian`` (n, 6, 7): J_v^T (-m g)."""
    force = -mass[:, None] * gravity[None, :]
    return np.einsum("nij,ni->nj", jacobian[:, :3, :], force)


class ArmDynamics:
    """Where M(q) and C(q, dq) dq + g(q) of n arms are read after every step
    (:meth:`model_rows`, for the contact sensing's C plan), and the Jacobian.

    Args:
        physics: the arms (after a step, mj_step1 has left M and the bias forces of
            the new state in every arm's MjData; see sim/arm.py).
    """

    def __init__(self, physics: ArmPhysics) -> None:
        self.physics = physics
        model, lay = physics.model, physics.layout
        datas = physics.datas
        dofs = np.asarray(lay.dof_adr[0])
        self._payload = lay.payload_body
        self._qfrc_bias = ArmRows([d.qfrc_bias for d in datas], dofs)
        self._passive = ArmRows([d.qfrc_passive for d in datas], dofs)
        # Where the arm's 7 x 7 block sits in MuJoCo's sparse inertia d.M: mj_fullM of a
        # probe whose M holds its own indices.
        probe = mujoco.MjData(model)
        probe.M[:] = np.arange(len(probe.M))
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, probe, full)
        block = full[np.ix_(dofs, dofs)].astype(np.intp)
        lo, hi = int(block.min()), int(block.max()) + 1
        # the arm's stretch of M, gathered as rows; the block indexed out of it
        self._qM = ArmRows([d.M for d in datas], np.arange(lo, hi))
        self._block = block - lo
        # refreshed by the arms with their measured state, after every step
        physics.gather_also(self._qfrc_bias, self._passive, self._qM)

    def model_rows(self) -> tuple:
        """What the model terms are read from after every step, for a C plan of them
        (fci/contact/_contact.c Sensing): the arm's stretch of MuJoCo's sparse inertia
        (n, L) and where the arm's 7 x 7 entries sit in it ((49,) int64,
        row-major), qfrc_bias and qfrc_passive (n, 7), and the weight of a payload the
        robot is not told of (n, 7; None without one). M(q) is the block; the bias
        C dq + g + friction is qfrc_bias minus the passive forces (the model's viscous
        joint damping, which the robot's model compensates like its real joint friction:
        left out, it would read as an external torque of 0.1 Nm per rad/s) minus that
        weight (a payload fixed to the flange without the robot being told is not its
        model; its inertia stays in M, a small error in fast motions). Their one text is
        the plan's (fci/contact/_contact.c)."""
        payload = None if self._payload is None else self.physics.payload_weight
        block = np.ascontiguousarray(self._block.reshape(-1), dtype=np.int64)
        return self._qM.out, block, self._qfrc_bias.out, self._passive.out, payload

    def jacobian(self, point: np.ndarray) -> np.ndarray:
        """(n, 6, 7) Jacobian of ``point`` (n, 3, base frame) on each arm's last link."""
        return self.physics.jacobian(point)
