"""Forward kinematics, the end-effector Jacobian and the IK solve of n arms.

The kinematics are MuJoCo's own, on a world of n bare arms stacked at the origin
(``build_world(n, spacing=0)``): each arm's frames there are computed exactly as the
one arm of the physics world computes them (the same chain from the same origin), so
the pose the IK solves for is exactly the pose the simulated arm reaches -- no second
kinematic model to drift from the first -- and one ``mj_kinematics`` serves all n arms.
The IK solve (the pose error, the damped Gauss-Newton step) has one text, in C
(sim/_ik.c, native/_ik_core.h); its settings and result are :mod:`franka_sim_gym.sim.ik`.

Batch-first: every call handles all n arms (one ``mj_kinematics`` for the stacked world
per evaluation, the Jacobian assembled for every arm at once from MuJoCo's
joint anchors and axes).
"""

from __future__ import annotations

import mujoco
import numpy as np

from .. import native
from .dynamics import jacobian_at
from .ik import ELBOW_JOINT, MAX_STEP, IkResult, mj_kinematics_addresses
from .layout import ArmLayout
from .views import strided_rows
from .world import build_world

__all__ = ["IK_KERNEL", "ArmKinematics"]

#: The one text of ArmKinematics.solve (sim/_ik.c, native/_ik_core.h; issue 38: no numpy
#: twin).
IK_KERNEL = native.require("sim._ik", "ik_solve")


class ArmKinematics:
    """Kinematics of n arms, on a private world of n arms stacked at the origin (physics
    is not touched).

    Args:
        model: the physics world (``ArmPhysics.model``): its arms' kinematics are those of
            models/fr3.xml at the origin, which the private world repeats.
        layout: its arm layout (``layout.n`` arms).
        damping: Levenberg-Marquardt damping lambda of the IK step; small, so the
            fixed point is the exact solution (damping only tames singular steps).
        max_iterations: Gauss-Newton updates per solve at most.
        tolerance: the pose error [m, rad] under which a solution counts as converged.
            A Gauss-Newton residual is smooth along a smooth trajectory (it scales
            with the square of the per-cycle step), so the joint-side checks, which
            difference solutions three times over 1 ms, do not see it.

    The solve runs every cycle at 1 kHz on small arrays, in C (sim/_ik.c), which calls
    MuJoCo's own ``mj_kinematics`` between its passes and reads and writes the arms' rows
    of the private MjData through views (every world ``world.py`` builds lays them out
    evenly). Where MuJoCo's function or those views cannot be had, construction raises
    a RuntimeError saying which.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        layout: ArmLayout,
        damping: float = 1e-4,
        max_iterations: int = 8,
        tolerance: float = 1e-7,
    ) -> None:
        # The arms' frames alone: the hands, the table and the objects change no link's pose.
        model, layout = build_world(n_arms=layout.n, spacing=0.0)
        self.model = model
        self.data = mujoco.MjData(model)
        self.layout = layout
        n = self.n = layout.n
        self.damping = damping
        self.max_iterations = max_iterations
        self.tolerance = tolerance
        joint_of_qpos = {int(model.jnt_qposadr[j]): j for j in range(model.njnt)}
        self._joints = np.array(
            [[joint_of_qpos[int(a)] for a in row] for row in layout.qpos_adr], dtype=np.intp
        )
        self._sites = np.asarray(layout.flange_site, dtype=np.intp)
        self._base = np.asarray(layout.base_pos, dtype=np.float64)
        self._qpos = layout.qpos_adr
        # The arms' rows of MjData as views (they stay put).
        self._rows = self._mjdata_rows()
        if self._rows is None:  # pragma: no cover - every world world.py builds has them
            raise RuntimeError("ArmKinematics: the arms' rows of MjData are not evenly spaced")
        # The last evaluation, reused when the next one is at the same q and frame;
        # written in place by every evaluation (forward and jacobian return copies).
        self._cached_q = np.full((n, 7), np.nan)
        self._cached = False
        self._cached_F: np.ndarray | None = None  # the EE frame it was evaluated at
        self._p = np.empty((n, 3))
        self._R = np.empty((n, 3, 3))
        self._R_out = self._R  # the rotations of the last evaluation (_R or MjData's rows)
        self._J = np.empty((n, 6, 7))
        # MjData's rows are at _cached_q / _cached_F (the evaluation's buffers may not be:
        # the C solve reads and moves the rows directly).
        self._rows_valid = False
        self._converged = np.empty(n, dtype=bool)  # the C solve's verdicts and errors
        self._errors = np.empty((2, n))
        addresses = mj_kinematics_addresses(model, self.data)
        if addresses is None:
            raise RuntimeError(
                "ArmKinematics: MuJoCo's mj_kinematics cannot be called from sim/_ik.c (no "
                "library exporting it beside the mujoco package, or no struct addresses)"
            )
        self._solver = self._solver_tuple(addresses)

    def _mjdata_rows(self) -> tuple | None:
        """Views of the private MjData's rows every evaluation reads and writes: qpos,
        the flange's position and rotation (n, 3, 3), the joints' axes and anchors; None
        when one is not a view."""
        d = self.data
        rows = (
            strided_rows(d.qpos, self._qpos),
            strided_rows(d.site_xpos, self._sites),
            strided_rows(d.site_xmat, self._sites),
            strided_rows(d.xaxis, self._joints),
            strided_rows(d.xanchor, self._joints),
        )
        if any(r is None for r in rows):
            return None
        qpos, site_pos, site_mat, axes, anchors = rows
        R_site = site_mat.reshape(self.n, 3, 3)
        if not np.shares_memory(R_site, d.site_xmat):  # pragma: no cover - reshape copied
            return None
        return qpos, site_pos, R_site, axes, anchors

    def _evaluate(self, q: np.ndarray, F_T_EE: np.ndarray | None):
        """EE position (n, 3), rotation (n, 3, 3) and Jacobian (n, 6, 7) at q.

        The arrays are the evaluation's own buffers: valid until the next evaluation.
        """
        # (a NaN in q never equals: evaluated afresh)
        same_q = self._cached and np.count_nonzero(q != self._cached_q) == 0
        if same_q and self._same_frame(F_T_EE):
            return self._p, self._R_out, self._J
        self._cached_F = None if F_T_EE is None else F_T_EE.copy()
        qpos, site_pos, R_site, axes, anchors = self._rows
        qpos[...] = q
        mujoco.mj_kinematics(self.model, self.data)
        if F_T_EE is not None:  # the EE frame on the flange: p + R_site F_p, R_site F_R
            p_world = site_pos + (R_site @ F_T_EE[:, :3, 3:])[..., 0]
            R = np.matmul(R_site, F_T_EE[:, :3, :3], out=self._R)
        else:  # the flange itself: MjData's rows as they are (they change only here)
            p_world, R = site_pos, R_site
        self._R_out = R
        np.subtract(p_world, self._base, out=self._p)  # base frame = world frame translated
        jacobian_at(axes, anchors, p_world, out=self._J)
        self._cached_q[...] = q
        self._cached = self._rows_valid = True
        return self._p, R, self._J

    def _same_frame(self, F_T_EE: np.ndarray | None) -> bool:
        cached = self._cached_F
        if F_T_EE is None or cached is None:
            return F_T_EE is None and cached is None
        return np.count_nonzero(F_T_EE != cached) == 0

    def forward(self, q: np.ndarray, F_T_EE: np.ndarray | None = None) -> np.ndarray:
        """(n, 4, 4) end-effector poses in each arm's base frame at joint positions q."""
        p, R, _ = self._evaluate(np.asarray(q, dtype=np.float64), F_T_EE)
        T = np.zeros((self.n, 4, 4))
        T[:, :3, :3] = R
        T[:, :3, 3] = p
        T[:, 3, 3] = 1.0
        return T

    def jacobian(self, q: np.ndarray, F_T_EE: np.ndarray | None = None) -> np.ndarray:
        """(n, 6, 7) geometric Jacobian (linear; angular, base frame) at the EE frame."""
        return self._evaluate(np.asarray(q, dtype=np.float64), F_T_EE)[2].copy()

    def solve(
        self,
        target: np.ndarray,
        q_init: np.ndarray,
        F_T_EE: np.ndarray | None = None,
        elbow: np.ndarray | None = None,
        rows: np.ndarray | None = None,
        out: np.ndarray | None = None,
    ) -> IkResult:
        """Damped Gauss-Newton from ``q_init`` to the (n, 4, 4) ``target`` poses.

        Each pass evaluates the arms at q, takes the pose error (position, and the
        rotation's as vee((E - E^T) / 2) of E = R_target R^T: sin(angle) times the axis),
        counts an arm converged once both
        its position and rotation errors are within ``tolerance``, and steps the active
        unconverged arms by the damped least-squares step J^T (J J^T + lambda^2 I)^-1 e,
        its largest joint change capped at ``ik.MAX_STEP``, up to ``max_iterations``
        steps. Its only text is C (sim/_ik.c, native/_ik_core.h).

        Args:
            target: commanded EE poses in the base frame (row-major 4x4).
            q_init: (n, 7) start (the previous cycle's solution).
            F_T_EE: (n, 4, 4) flange-to-EE transforms, None for identity.
            elbow: (n,) joint-3 angles to hold fixed (NaN where the elbow is free:
                ``valid_elbow`` false), or None for every elbow free.
            rows: (n,) bool, the arms to solve (others keep ``q_init``).
            out: an (n, 7) array to iterate in and return as the solution (default: new).
        """
        q = np.empty((self.n, 7)) if out is None else out
        if rows is not None:
            rows = np.asarray(rows, dtype=bool)
        if elbow is not None:
            elbow = np.asarray(elbow, dtype=np.float64)
        q_init = np.asarray(q_init, dtype=np.float64)
        IK_KERNEL.ik_solve(q_init, q, target, F_T_EE, elbow, rows, self._rows_valid, self._solver)
        # MjData's rows are now at the last iterate, the evaluation's buffers are not.
        self._rows_valid, self._cached = True, False
        converged = self._converged.copy() if rows is None else self._converged | ~rows
        position_error, rotation_error = self._errors.copy()  # (the next solve reuses them)
        return IkResult(q, converged, position_error, rotation_error)

    def _solver_tuple(self, addresses: tuple) -> tuple:
        """What the C solve reads and writes (native/_ik_core.h ik_solver_get)."""
        qpos, site_pos, R_site, axes, anchors = self._rows
        return (
            self._cached_q, qpos, site_pos, R_site, axes, anchors, self._base,
            self._errors, self._converged, self.damping**2, self.tolerance**2, MAX_STEP,
            self.max_iterations, addresses, ELBOW_JOINT,
        )  # fmt: skip

    @property
    def native_solve(self) -> tuple:
        """The C solve's arrays, settings and mj_kinematics addresses (native/_ik_core.h),
        as :meth:`solve` passes them to ``ik_solve``."""
        return self._solver
