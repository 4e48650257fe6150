"""The robot's model against the arm: where its gravity compensation and its estimate
are wrong because the arm's links are not those of its model (docs/reality.md, "Model").

The FCI compensates gravity and estimates the external torque with its own model (the
URDF GetRobotModel serves); a real arm's links weigh and balance differently ("averaged
across many robots", franka_ros #404). The difference at a configuration is the gravity
torque of the links' differences in mass m and first moment m c:

    dg_j(q) = g_arm_j(q) - g_model_j(q)
            = G (z_j x sum_{i >= j} [ dm_i (p_i - o_j) + R_i d(mc)_i ])_z,

z_j, o_j joint j's axis and a point of it, p_i, R_i link i's frame (all of the arm's
current state: the kinematics are the model's), G the gravity's magnitude along -z. The
drives then carry the model's weight, not the arm's (the arm sags until its servo takes
up dg), and the estimate reads dg as an external torque at rest: the pose-dependent
offset of a real robot's tau_ext_hat_filtered and O_F_ext_hat_K.
"""

from __future__ import annotations

import numpy as np

from ...sim.arm import ArmPhysics
from ...sim.views import ArmRows


class GravityResidual:
    """dg(q) of n robots, the module docstring's formula in eleven numpy calls.

    Args:
        physics: the arms; their shared (nominal) model is the robot's model. The links'
            frames are gathered with the measured state after every step.
    """

    def __init__(self, physics: ArmPhysics) -> None:
        model, lay = physics.model, physics.layout
        n = physics.n
        gravity = np.asarray(model.opt.gravity, dtype=float)
        if np.any(gravity[:2] != 0.0) or gravity[2] >= 0.0:  # pragma: no cover - fr3.xml's
            raise ValueError(f"the model's gravity must point along -z, got {gravity}")
        self._g = float(-gravity[2])
        links = lay.link_body[0, 1:8]
        self._mass = model.body_mass[links].copy()
        self._com = model.body_ipos[links].copy()
        datas = physics.datas
        self._xpos = ArmRows([d.xpos for d in datas], links)
        self._xmat = ArmRows([d.xmat for d in datas], links)
        physics.gather_also(self._xpos, self._xmat)
        self._axes, self._anchors = physics.joint_axes, physics.joint_anchors
        # G dm (n, 7), G d(mc) (n, 7, 3), G sum_{i >= j} dm_i (n, 7): the draw's
        self._dm = np.zeros((n, 7))
        self._dmc = np.zeros((n, 7, 1, 3))
        self._tail_mass = np.zeros((n, 7, 1))
        self._t33 = np.zeros((n, 7, 3, 3))
        self._w = np.zeros((n, 7, 3))
        self._t3 = np.zeros((n, 7, 3))
        self._sums = np.zeros((n, 7, 3))
        self._a = np.zeros((n, 7))
        self._b = np.zeros((n, 7))
        self.out = np.zeros((n, 7))

    def set(self, robots, mass_scale, com_offset) -> None:
        """The arms of ``robots`` have the model's link masses times ``mass_scale`` (k, 7)
        and centres of mass moved by ``com_offset`` (k, 7, 3, link frames)."""
        m0, c0 = self._mass, self._com
        m = m0 * np.asarray(mass_scale)
        mc = m[..., None] * (c0 + np.asarray(com_offset))
        dm = self._g * (m - m0)
        self._dm[robots] = dm
        self._dmc[robots, :, 0] = self._g * (mc - m0[:, None] * c0)
        self._tail_mass[robots, :, 0] = np.cumsum(dm[..., ::-1], axis=-1)[..., ::-1]

    def residual(self) -> np.ndarray:
        """(n, 7) dg at the arms' current state (``out``, overwritten by the next call)."""
        R = self._xmat.out.reshape(-1, 7, 3, 3)
        np.multiply(R, self._dmc, out=self._t33)
        w = np.sum(self._t33, axis=3, out=self._w)  # R_i d(mc)_i
        np.multiply(self._xpos.out, self._dm[..., None], out=self._t3)
        w += self._t3  # + dm_i p_i
        sums = np.cumsum(w[:, ::-1], axis=1, out=self._sums)[:, ::-1]  # over i >= j
        np.multiply(self._anchors, self._tail_mass, out=self._t3)
        v = np.subtract(sums, self._t3, out=self._t3)  # - (sum dm_i) o_j
        axes = self._axes
        np.multiply(v[..., 1], axes[..., 0], out=self._a)
        np.multiply(v[..., 0], axes[..., 1], out=self._b)
        return np.subtract(self._a, self._b, out=self.out)
