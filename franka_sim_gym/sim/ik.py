"""The damped differential IK's rule: the pose error and the damped Gauss-Newton step.

The Cartesian motion generators are judged and driven in joint space (docs/fci-behaviour.md,
The joint side of a Cartesian command): every commanded pose is solved to a joint
configuration by damped Gauss-Newton from the previous cycle's solution.
:class:`~franka_sim_gym.sim.kinematics.ArmKinematics` runs the passes (evaluate, error,
verdict, step) on MuJoCo's kinematics; this module holds what one pass computes, as pure
batch-first functions, and the solver's settings.

Its whole-solve C replacement is ``sim/_ik.c`` (``native/_ik_core.h``), chosen by the
one backend switch (``native.load``, ``FRANKA_SIM_GYM_NATIVE``): the same passes and
verdicts; the solution agrees to rounding (~1e-14 rad), not bit for bit, as its 6x6
solve is an elimination with partial pivoting where numpy calls LAPACK's ``gesv``
(tests/sim/test_ik_native.py).
"""

from __future__ import annotations

import ctypes
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from .rotations import LEVI_CIVITA

__all__ = [
    "ELBOW_JOINT",
    "MAX_STEP",
    "USABLE_POSITION_ERROR",
    "USABLE_ROTATION_ERROR",
    "IkResult",
    "damped_step",
    "mj_kinematics_addresses",
    "pose_error",
]

#: Joint 3 is the FR3's redundancy angle (RobotState's elbow[0] is q[2]).
ELBOW_JOINT = 2

#: The largest joint change [rad] of one Gauss-Newton update. A tracked pose moves the
#: solution by milliradians a cycle; only a jump to an unreachable pose hits this.
MAX_STEP = 0.5

#: A solution this close to its target [m, rad] still drives the servo when the solve
#: stopped short of its tolerance (near a singularity); farther, the target is
#: unreachable from here and the servo holds the last usable solution.
USABLE_POSITION_ERROR = 1e-3
USABLE_ROTATION_ERROR = 1e-2


class IkResult(NamedTuple):
    """What :meth:`ArmKinematics.solve <franka_sim_gym.sim.kinematics.ArmKinematics.solve>`
    returns."""

    #: (n, 7) joint positions.
    q: np.ndarray
    #: (n,) bool: the pose error fell below the tolerance.
    converged: np.ndarray
    #: (n,) the remaining position error [m] and rotation error [rad].
    position_error: np.ndarray
    rotation_error: np.ndarray


def pose_error(target: np.ndarray, p: np.ndarray, R: np.ndarray, out: np.ndarray) -> np.ndarray:
    """(n, 6) the pose error of (n, 3) positions ``p`` and (n, 3, 3) rotations ``R`` to the
    (n, 4, 4) ``target``, written into ``out``: ``[p_t - p | vee((E - E^T) / 2)]`` of
    ``E = R_t R^T``.

    The rotation half is sin(angle) * axis: zero exactly where the rotations agree,
    like the logarithm but cheaper, so Gauss-Newton converges to the same solution;
    its magnitude is the angle to within 0.2 % below 0.1 rad.
    """
    np.subtract(target[:, :3, 3], p, out=out[:, :3])
    np.einsum("iab,nak,nbk->ni", _HALF_VEE, target[:, :3, :3], R, out=out[:, 3:])
    return out


def damped_step(
    J: np.ndarray,
    e: np.ndarray,
    damping: float,
    held: np.ndarray | None = None,
    todo: np.ndarray | None = None,
) -> np.ndarray:
    """(n, 7) one damped Gauss-Newton step ``J^T (J J^T + damping^2 I)^-1 e`` of (n, 6, 7)
    Jacobians and (n, 6) errors.

    ``held``: (n,) bool, the arms whose elbow (joint :data:`ELBOW_JOINT`) is held (its
    column of J zeroed); ``todo``: (n,) bool, the arms to step (the others get zero; None:
    all). Where a joint of any arm would move more than :data:`MAX_STEP`, each arm's step
    is scaled down to at most that (an unreachable target makes the damped step grow
    without bound near a singularity: a solve that cannot converge cannot run away).
    """
    if held is not None and np.count_nonzero(held):
        J = J.copy()
        J[held, :, ELBOW_JOINT] = 0.0
    Jt = J.transpose(0, 2, 1)
    JJt = J @ Jt
    JJt += _EYE6 * damping**2
    step = (Jt @ np.linalg.solve(JJt, e[..., None]))[..., 0]
    if todo is not None:
        step[~todo] = 0.0
    biggest = np.abs(step).max(axis=1)
    if np.count_nonzero(biggest > MAX_STEP):
        step *= np.minimum(1.0, MAX_STEP / np.maximum(biggest, MAX_STEP))[:, None]
    return step


def mj_kinematics_addresses(model: mujoco.MjModel, data: mujoco.MjData) -> tuple | None:
    """(mj_kinematics, model, data) as addresses, for the C solve to call MuJoCo's own
    forward kinematics; None where they cannot be had (the numpy solve then runs).

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


_EYE6 = np.eye(6)
_EYE6.setflags(write=False)

#: pose_error's rotation half: vee((E - E^T) / 2) of E = R_t R^T as -eps / 2 contracted
#: with R_t and R in one call.
_HALF_VEE = -0.5 * LEVI_CIVITA
