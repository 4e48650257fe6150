"""Forward kinematics, the end-effector Jacobian and damped differential IK of n arms.

The Cartesian motion generators are judged and driven in joint space (seed
"The joint side of a Cartesian command (29, 30)"): every commanded pose is
solved to a joint configuration by damped Gauss-Newton from the previous
cycle's solution, at the end-effector frame the arm is driven in (F_T_EE,
SetNEToEE included). The kinematics are MuJoCo's own, on a second MjData of
the physics model, so the pose the IK solves for is exactly the pose the
simulated arm reaches — no second kinematic model to drift from the first.

Batch-first: every call handles all n arms of the world (one ``mj_kinematics``
for the whole world per iteration, the Jacobian assembled for every arm at
once from MuJoCo's joint anchors and axes).
"""

from __future__ import annotations

import ctypes
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np
from numpy import count_nonzero, einsum

from .. import native
from .views import strided_rows
from .world import ArmLayout

try:  # numpy's batched LAPACK solve, without np.linalg.solve's Python checks (~2 us a call)
    from numpy.linalg._umath_linalg import solve as _solve
except ImportError:  # pragma: no cover - other numpy layouts
    _solve = np.linalg.solve


#: Joint 3 is the FR3's redundancy angle (seed "RobotState fields": elbow[0] = q[2]).
ELBOW_JOINT = 2


class IkResult(NamedTuple):
    """What :meth:`ArmKinematics.solve` returns."""

    #: (n, 7) joint positions.
    q: np.ndarray
    #: (n,) bool: the pose error fell below the tolerance.
    converged: np.ndarray
    #: (n,) the remaining position error [m] and rotation error [rad].
    position_error: np.ndarray
    rotation_error: np.ndarray


def rotation_log(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 3) rotation vectors (axis * angle).

    The angle is atan2(|vee|, (trace - 1) / 2), exact over [0, pi]; the axis is the
    skew part's direction, except within 1e-6 of pi, where the skew part vanishes
    and the axis comes from the symmetric part.
    """
    flat = R.reshape(*R.shape[:-2], 9)
    # (R21 - R12, R02 - R20, R10 - R01): one gather each side instead of three stacks.
    out = flat[..., _VEE_PLUS] - flat[..., _VEE_MINUS]
    angle = _scale_to_angle(out, flat[..., 0] + flat[..., 4] + flat[..., 8] - 1.0)
    near_pi = np.pi - angle < 1e-6
    if count_nonzero(near_pi):
        sym = (R[near_pi] + np.eye(3)) * 0.5
        k = np.argmax(np.diagonal(sym, axis1=-2, axis2=-1), axis=-1)
        axis = sym[np.arange(len(k)), :, k]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        out[near_pi] = axis * angle[near_pi][..., None]
    return out


def relative_rotation_log(
    R_a: np.ndarray, R_b: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """(n, 3) ``rotation_log(R_a^T R_b)`` of (n, 3, 3) pairs, without forming the product
    away from pi: its skew part and trace are contractions of R_a with R_b. ``out``: an
    (n, 3) array to write the result into (and return)."""
    n = len(R_a)
    if out is None:
        vee = einsum("iab,nka,nkb->ni", _NEG_LEVI_CIVITA, R_a, R_b)
    else:
        vee = einsum("iab,nka,nkb->ni", _NEG_LEVI_CIVITA, R_a, R_b, out=out)
    # 2 sin(angle) and 2 cos(angle) side by side, so that one comparison screens both
    sin_cos = np.empty((n, 2))
    two_sin, two_cos = sin_cos[:, 0], sin_cos[:, 1]
    einsum("nka,nka->n", R_a, R_b, out=two_cos)
    two_cos -= 1.0
    np.sqrt(einsum("ni,ni->n", vee, vee), out=two_sin)
    angle = np.arctan2(two_sin, two_cos)
    screen = sin_cos > _TURNING_ACUTE
    screened = count_nonzero(screen)
    if screened == 2 * n:
        # Every angle turning and below pi / 2 (so far from pi): the common case.
        vee *= (angle / two_sin)[:, None]
        return vee
    if screened == n and count_nonzero(screen[:, 1]) == n:
        # None turning, every angle below pi / 2 (a pure translation): the limit 1/2.
        vee *= 0.5
        return vee
    _scale_vee(vee, two_sin, angle)
    near_pi = np.pi - angle < 1e-6
    if count_nonzero(near_pi):  # the skew part vanishes: rotation_log's branch
        vee[near_pi] = rotation_log(R_a[near_pi].transpose(0, 2, 1) @ R_b[near_pi])
    return vee


def _scale_to_angle(vee: np.ndarray, two_cos: np.ndarray) -> np.ndarray:
    """Scale the skew part ``vee`` (2 sin(angle) axis) to angle * axis in place; return
    the angle, atan2(|vee|, 2 cos(angle)), exact over [0, pi]."""
    two_sin = np.sqrt(einsum("...i,...i->...", vee, vee))
    angle = np.arctan2(two_sin, two_cos)
    _scale_vee(vee, two_sin, angle)
    return angle


def _scale_vee(vee: np.ndarray, two_sin: np.ndarray, angle: np.ndarray) -> None:
    """vee (2 sin(angle) axis) *= angle / (2 sin(angle)), in place."""
    turning = two_sin > 1e-12
    if count_nonzero(turning) == turning.size:
        vee *= (angle / two_sin)[..., None]
    else:  # angle / (2 sin angle) -> 1/2 as the angle -> 0
        vee *= np.where(turning, angle / np.where(turning, two_sin, 1.0), 0.5)[..., None]


def skew(u: np.ndarray) -> np.ndarray:
    """(..., 3) vectors to (..., 3, 3) cross-product matrices: skew(u) @ v = u x v."""
    lead = u.shape[:-1]
    # [0, u, -u], then one gather of the nine entries (fancy assignment costs ~3x more)
    padded = np.empty(lead + (7,), dtype=u.dtype)
    padded[..., 0] = 0.0
    padded[..., 1:4] = u
    np.negative(u, out=padded[..., 4:])
    return padded.take(_SKEW_FROM_PADDED, -1).reshape(lead + (3, 3))


def rotation_exp(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors to (..., 3, 3) matrices (Rodrigues)."""
    # np.linalg.norm's own arithmetic, without its dispatch.
    angle = np.sqrt(np.add.reduce(rotvec * rotvec, axis=-1))
    small = angle < 1e-8
    K = skew(rotvec)
    if count_nonzero(small):
        safe = np.where(small, 1.0, angle)
        a = np.where(small, 1.0 - angle**2 / 6.0, np.sin(angle) / safe)
        b = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(angle)) / safe**2)
    else:  # the same arithmetic, without the series' branch
        a = np.sin(angle) / angle
        b = (1.0 - np.cos(angle)) / angle**2
    return _EYE3 + a[..., None, None] * K + b[..., None, None] * (K @ K)


_EYE3 = np.eye(3)
_EYE3.setflags(write=False)

#: [2 sin, 2 cos] strictly above these: the angle turns (the ratio angle / (2 sin) is
#: computed as is) and is below pi / 2 (atan2 of a positive cosine), far from pi.
_TURNING_ACUTE = np.array([1e-12, 0.0])

#: rotation_log's skew part in the flat row-major matrix: entries 7 - 5, 2 - 6, 3 - 1.
_VEE_PLUS = np.array([7, 2, 3])
_VEE_MINUS = np.array([5, 6, 1])
#: skew(k) flat, row-major, from [0, kx, ky, kz, -kx, -ky, -kz]: entries (0, 1), (0, 2),
#: (1, 0), (1, 2), (2, 0), (2, 1) are -kz, ky, kz, -kx, -ky, kx; the diagonal is zero.
_SKEW_FROM_PADDED = np.array([0, 6, 2, 3, 0, 4, 5, 1, 0])


#: The Levi-Civita symbol: (a x b)_i = eps_iab a_a b_b.
_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0

#: vee(M - M^T) of M = R_a^T R_b is -eps_iab R_a[k, a] R_b[k, b].
_NEG_LEVI_CIVITA = -_LEVI_CIVITA

#: The IK's rotation error: vee((E - E^T) / 2) of E = R_t R^T, i.e. sin(angle) * axis,
#: as -eps / 2 contracted with R_t and R in one call. Zero exactly where the rotations
#: agree, like the logarithm but cheaper, so Gauss-Newton converges to the same
#: solution; its magnitude is the angle to within 0.2 % below 0.1 rad.
_HALF_VEE = -0.5 * _LEVI_CIVITA

#: The largest joint change [rad] of one Gauss-Newton update. A tracked pose moves the
#: solution by milliradians a cycle; only a jump to an unreachable pose hits this.
MAX_STEP = 0.5

#: A solution this close to its target [m, rad] still drives the servo when the solve
#: stopped short of ``tolerance`` (near a singularity); farther, the target is
#: unreachable from here and the servo holds the last usable solution.
USABLE_POSITION_ERROR = 1e-3
USABLE_ROTATION_ERROR = 1e-2


def _mujoco_kinematics(model: mujoco.MjModel, data: mujoco.MjData) -> tuple | None:
    """(mj_kinematics, model, data) as addresses, for the IK kernel to call MuJoCo's own
    forward kinematics from C; None where they cannot be had (the numpy loop then runs).

    The function is looked up in the libmujoco the Python bindings ship and have loaded
    (the same library, so the same code as ``mujoco.mj_kinematics``); the structs'
    addresses are the bindings' ``_address`` (tested in MuJoCo's own bindings tests).
    The caller keeps ``model`` and ``data`` alive as long as the addresses are used.
    """
    model_address = getattr(model, "_address", None)
    data_address = getattr(data, "_address", None)
    if not model_address or not data_address:
        return None
    package = Path(mujoco.__file__).parent
    for library in sorted(package.glob("*mujoco*")):
        if library.suffix not in {".so", ".dylib", ".dll"} and ".so." not in library.name:
            continue
        if library.name.startswith("_"):  # the bindings' own extension modules
            continue
        try:
            function = ctypes.CDLL(str(library)).mj_kinematics
        except (OSError, AttributeError):
            continue
        address = ctypes.cast(function, ctypes.c_void_p).value
        if address:
            return (address, int(model_address), int(data_address))
    return None


class ArmKinematics:
    """Kinematics of the n arms of a world, on a private MjData (physics is not touched).

    Args:
        model: the compiled world (``world.build_world``).
        layout: its arm layout.
        damping: Levenberg-Marquardt damping lambda of the IK step; small, so the
            fixed point is the exact solution (damping only tames singular steps).
        max_iterations: Gauss-Newton updates per solve at most.
        tolerance: the pose error [m, rad] under which a solution counts as converged.
            A Gauss-Newton residual is smooth along a smooth trajectory (it scales
            with the square of the per-cycle step), so the joint-side checks, which
            difference solutions three times over 1 ms, do not see it.
        kernel: solve through the C kernel (sim/_ik.c) where it is built and the
            arms' rows are views (the controller's 1 kHz path); False: the numpy
            reference, bit for bit (the kernel agrees with it to rounding).

    The solve runs every cycle at 1 kHz on small arrays, where each numpy call costs
    about as much as its arithmetic: the scratch arrays are allocated once, and the
    arms' rows of MjData are read and written through views where the layout allows.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        layout: ArmLayout,
        damping: float = 1e-4,
        max_iterations: int = 8,
        tolerance: float = 1e-7,
        kernel: bool = False,
    ) -> None:
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
        self._eye6 = np.eye(6) * damping**2
        # The arms' rows of MjData as views (they stay put), or None where an index is
        # not evenly spaced (every world built by world.py is): gathered each evaluation.
        self._rows = self._mjdata_rows()
        # The last evaluation, reused when the next solve starts where it ended; written
        # in place by every evaluation (callers get copies).
        self._cached_q = np.full((n, 7), np.nan)
        self._cached = False
        self._cached_F: np.ndarray | None = None  # the EE frame it was evaluated at
        self._p = np.empty((n, 3))
        self._R = np.empty((n, 3, 3))
        self._R_out = self._R  # the rotations of the last evaluation (_R or MjData's rows)
        self._J = np.empty((n, 6, 7))
        self._Jt = self._J.transpose(0, 2, 1)
        self._J_linear, self._J_angular = self._J[:, :3], self._J[:, 3:]
        # Scratch of one evaluation and one Gauss-Newton update.
        self._p_world = np.empty((n, 3))
        self._offset = np.empty((n, 3, 1))
        self._lever = np.empty((n, 7, 3))
        self._same_q = np.empty((n, 7), dtype=bool)
        self._JJt = np.empty((n, 6, 6))
        self._step = np.empty((n, 7, 1))
        self._step_flat = self._step[..., 0]
        self._abs_step = np.empty((n, 7))
        self._big = np.empty((n, 7), dtype=bool)
        self._e = np.empty((n, 6))  # the pose error [position | rotation]
        self._e_col = self._e[..., None]
        self._halves = self._e.reshape(n, 2, 3)
        self._e_pos, self._e_rot = self._halves[:, 0], self._halves[:, 1]
        self._err2 = np.empty((n, 2))
        self._ok = np.empty((n, 2), dtype=bool)
        # Read-only verdicts every arm shares (returned as IkResult.converged).
        self._all = np.ones(n, dtype=bool)
        self._all.setflags(write=False)
        self._none = np.zeros(n, dtype=bool)
        self._none.setflags(write=False)
        # MjData's rows are at _cached_q / _cached_F (the evaluation buffers above may not
        # be: the kernel's solve reads the rows directly).
        self._rows_valid = False
        # The C kernel's solve (sim/_ik.c), where built, the rows are views and MuJoCo's
        # mj_kinematics can be called from C (the addresses it needs).
        self._mj_kinematics = _mujoco_kinematics(model, self.data) if kernel else None
        self._kernel = native.load("sim._ik") if self._mj_kinematics is not None else None
        self._converged = np.empty(n, dtype=bool)  # the kernel's verdicts and errors
        self._errors = np.empty((2, n))
        self._native_solve: tuple | None = None  # built on first use (native_solve)

    def _mjdata_rows(self) -> tuple | None:
        """Views of the private MjData's rows every evaluation reads and writes: qpos,
        the flange's position (also as (n, 1, 3)) and rotation (n, 3, 3), the joints'
        axes (also transposed) and anchors; None when one is not a view."""
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
        return qpos, site_pos, site_pos[:, None, :], R_site, axes, axes.transpose(0, 2, 1), anchors

    def _evaluate(self, q: np.ndarray, F_T_EE: np.ndarray | None):
        """EE position (n, 3), rotation (n, 3, 3) and Jacobian (n, 6, 7) at q.

        The arrays are the evaluation's own buffers: valid until the next evaluation.
        """
        if (
            self._cached
            and count_nonzero(np.equal(q, self._cached_q, out=self._same_q)) == q.size
            and self._same_frame(F_T_EE)
        ):
            return self._p, self._R_out, self._J
        self._cached_F = None if F_T_EE is None else F_T_EE.copy()
        d = self.data
        if self._rows is not None:
            qpos, site_pos, site_col, R_site, axes, axes_t, anchors = self._rows
            qpos[...] = q
            mujoco.mj_kinematics(self.model, d)
        else:
            d.qpos[self._qpos] = q
            mujoco.mj_kinematics(self.model, d)
            site_pos = d.site_xpos[self._sites]
            site_col = site_pos[:, None, :]
            R_site = d.site_xmat[self._sites].reshape(self.n, 3, 3)
            axes = d.xaxis[self._joints]  # (n, 7, 3)
            axes_t = axes.transpose(0, 2, 1)
            anchors = d.xanchor[self._joints]
        if F_T_EE is not None:
            p_world, R = self._p_world, self._R
            np.matmul(R_site, F_T_EE[:, :3, 3:], out=self._offset)
            np.add(site_pos, self._offset[..., 0], out=p_world)
            np.matmul(R_site, F_T_EE[:, :3, :3], out=R)
            site_col = p_world[:, None, :]
        else:  # the flange itself: MjData's rows as they are (they change only here)
            p_world, R = site_pos, R_site
        self._R_out = R
        np.subtract(p_world, self._base, out=self._p)
        # base frame = world frame (bases unrotated)
        np.subtract(site_col, anchors, out=self._lever)
        # Linear part: axis x (EE point - joint anchor), as one contraction with the
        # Levi-Civita symbol (np.cross, or the products written out, cost 3x more here).
        einsum("iab,nja,njb->nij", _LEVI_CIVITA, axes, self._lever, out=self._J_linear)
        self._J_angular[...] = axes_t
        self._cached_q[...] = q
        self._cached = self._rows_valid = True
        return self._p, R, self._J

    def _same_frame(self, F_T_EE: np.ndarray | None) -> bool:
        cached = self._cached_F
        if F_T_EE is None or cached is None:
            return F_T_EE is None and cached is None
        return count_nonzero(F_T_EE == cached) == F_T_EE.size

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

        Args:
            target: commanded EE poses in the base frame (row-major 4x4).
            q_init: (n, 7) start (the previous cycle's solution).
            F_T_EE: (n, 4, 4) flange-to-EE transforms, None for identity.
            elbow: (n,) joint-3 angles to hold fixed (NaN where the elbow is free:
                ``valid_elbow`` false), or None for every elbow free.
            rows: (n,) bool, the arms to solve (others keep ``q_init``).
            out: an (n, 7) array to iterate in and return as the solution (default: new).
        """
        if self._kernel is not None and self._rows is not None:
            return self._solve_native(target, q_init, F_T_EE, elbow, rows, out)
        n = self.n
        if out is None:
            q = np.array(q_init, dtype=np.float64, copy=True)
        else:
            q = out
            q[...] = q_init
        active = self._all if rows is None else np.asarray(rows, dtype=bool)
        n_active = n if rows is None else count_nonzero(active)
        all_active = n_active == n
        fixed = None
        if elbow is not None:
            fixed = active & np.isfinite(elbow)
            if count_nonzero(fixed):
                q[fixed, ELBOW_JOINT] = elbow[fixed]
            else:
                fixed = None
        p_t, R_t = target[:, :3, 3], target[:, :3, :3]
        err2, ok, halves = self._err2, self._ok, self._halves
        e_pos, e_rot = self._e_pos, self._e_rot
        tol2 = self.tolerance**2
        converged = self._all
        for iteration in range(self.max_iterations + 1):
            p, R, J = self._evaluate(q, F_T_EE)
            np.subtract(p_t, p, out=e_pos)
            einsum("iab,nak,nbk->ni", _HALF_VEE, R_t, R, out=e_rot)
            # Squared position and rotation errors side by side, (n, 2); converged where
            # both are within tolerance (NaN: not converged).
            einsum("nkj,nkj->nk", halves, halves, out=err2)
            np.less_equal(err2, tol2, out=ok)
            n_ok = count_nonzero(ok)
            if n_ok == 2 * n:  # every arm converged (the usual last pass)
                converged = self._all
                break
            if n_ok < 2:  # no arm has both halves in (the usual first pass)
                converged, todo, n_todo = self._none, active, n_active
            else:
                converged = ok[:, 0] & ok[:, 1]
                todo = ~converged if all_active else active & ~converged
                n_todo = count_nonzero(todo)
            if iteration == self.max_iterations or not n_todo:
                break
            q += self._update(J, fixed, None if n_todo == n else todo)
        position_error, rotation_error = np.sqrt(err2).T
        converged = converged if all_active else converged | ~active
        return IkResult(q, converged, position_error, rotation_error)

    def _solve_native(self, target, q_init, F_T_EE, elbow, rows, out) -> IkResult:
        """:meth:`solve` in one ``ik_solve`` call (sim/_ik.c): the same passes, each the
        evaluation from MjData's rows, the error, the verdicts and the damped step, with
        MuJoCo's own ``mj_kinematics`` between them, called from C. The same verdicts and
        errors as the numpy loop; the solution agrees to rounding (a 6x6 elimination in
        place of LAPACK's)."""
        n = self.n
        q = np.empty((n, 7)) if out is None else out
        if rows is not None:
            rows = np.asarray(rows, dtype=bool)
        if elbow is not None:
            elbow = np.asarray(elbow, dtype=np.float64)
        if type(q_init) is not np.ndarray or q_init.dtype != np.float64:  # (lists, float32)
            q_init = np.asarray(q_init, dtype=np.float64)
        self._kernel.ik_solve(
            q_init, q, target, F_T_EE, elbow, rows, self._rows_valid, self.native_solve
        )
        self.solved_natively()
        converged, errors = self._converged, self._errors
        if count_nonzero(converged) == n:
            verdict = self._all
        else:
            verdict = converged.copy() if rows is None else converged | ~rows
        position_error, rotation_error = errors.copy()  # (the next solve reuses errors)
        return IkResult(q, verdict, position_error, rotation_error)

    @property
    def native_solve(self) -> tuple | None:
        """What a fused kernel needs to run :meth:`solve` in C on this object's MjData
        (native/_ik_core.h; fci/_cartesian_rules.c plain_cycle): (cached_q, qpos,
        site_pos, site_mat, axes, anchors, base, errors, converged, damping^2,
        tolerance^2, MAX_STEP, max_iterations, the mj_kinematics addresses); None where
        the kernel path is off. Call :meth:`solved_natively` after every such solve."""
        if self._kernel is None or self._rows is None:
            return None
        if self._native_solve is None:
            qpos, site_pos, _, R_site, axes, _, anchors = self._rows
            self._native_solve = (
                self._cached_q, qpos, site_pos, R_site, axes, anchors, self._base,
                self._errors, self._converged, self.damping**2, self.tolerance**2, MAX_STEP,
                self.max_iterations, self._mj_kinematics,
            )  # fmt: skip
        return self._native_solve

    @property
    def rows_valid(self) -> bool:
        """MjData's rows are at the last solve's iterate (a fused solve may skip
        mj_kinematics when it starts there)."""
        return self._rows_valid

    def solved_natively(self) -> None:
        """A fused kernel solved on this object's MjData: its rows are at the last iterate,
        the numpy evaluation's buffers are not."""
        self._rows_valid, self._cached = True, False

    def _update(
        self, J: np.ndarray, fixed: np.ndarray | None, todo: np.ndarray | None
    ) -> np.ndarray:
        """(n, 7) one damped Gauss-Newton step J^T (J J^T + lambda^2 I)^-1 e, zero where
        the elbow is held (``fixed``'s joint 3) and outside ``todo`` (None: every arm)."""
        Jt = self._Jt
        if fixed is not None:
            J = J.copy()
            J[fixed, :, ELBOW_JOINT] = 0.0
            Jt = J.transpose(0, 2, 1)
        JJt = np.matmul(J, Jt, out=self._JJt)
        JJt += self._eye6
        np.matmul(Jt, _solve(JJt, self._e_col), out=self._step)
        step = self._step_flat
        if todo is not None:
            step[~todo] = 0.0
        # An unreachable target makes the damped step grow without bound near a
        # singularity; cap it, so a solve that cannot converge cannot run away.
        size = np.abs(step, out=self._abs_step)
        if count_nonzero(np.greater(size, MAX_STEP, out=self._big)):
            biggest = size.max(axis=1)
            step *= np.minimum(1.0, MAX_STEP / np.maximum(biggest, MAX_STEP))[:, None]
        return step
