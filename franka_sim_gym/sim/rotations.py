"""Rotations, batch-first: the one rotation library of the package.

Rotation matrices are row-major ``(..., 3, 3)`` arrays; rotation vectors ``(..., 3)`` are
axis * angle with the angle in [0, pi]; quaternions ``(..., 4)`` are (w, x, y, z), as
Eigen stores them. The simulation's IK, the controller's Cartesian rules and the env's
libfranka client filters all use these functions, so a pose is differentiated and
integrated the same way everywhere.

* :func:`skew`, :func:`rotation_exp` (Rodrigues) and :func:`rotation_log` /
  :func:`relative_rotation_log` (the matrix logarithm);
* :func:`rotation_to_quaternion`, :func:`quaternion_to_rotation` and
  :func:`quaternion_slerp`: Eigen's ``Quaterniond`` conversions and ``slerp``, which
  libfranka's ``cartesianLowpassFilter`` (src/lowpass_filter.cpp) runs on;
* :func:`nearest_rotation`: the orthonormal matrix nearest a nearly orthonormal one
  (Eigen's ``Affine3d::rotation()``, a polar decomposition).

Their one text is C, one rotation at a time (``native/_rotation.h``, which the client's
pose filters in ``envs/_client_filters.c`` call directly; ``sim/_rotations.c`` runs it over
the rows of an array): at one arm a rotation costs a call, not a dozen numpy calls, and a
row's bits do not depend on how many rows are in the batch or on the CPU's BLAS kernel
(products sum over k = 0, 1, 2, without fused multiply-adds). Here: the thresholds and
numpy's leading axes.
"""

from __future__ import annotations

import numpy as np

from .. import native

__all__ = [
    "NEAR_PI",
    "SERIES_BELOW",
    "SLERP_LINEAR",
    "TURNING_ABOVE",
    "nearest_rotation",
    "quaternion_slerp",
    "quaternion_to_rotation",
    "relative_rotation_log",
    "rotation_exp",
    "rotation_log",
    "rotation_to_quaternion",
    "skew",
]

#: Eigen's QuaternionBase::slerp interpolates linearly once |dot| >= 1 - epsilon.
SLERP_LINEAR = 1.0 - float(np.finfo(np.float64).eps)

#: Within this of a half turn [rad] the skew part of R, 2 sin(angle) axis, has too few
#: significant bits for the axis (its rounding is ~1e-16 absolute): rotation_log takes
#: the axis from the quaternion there (Shepperd's method, exact up to pi).
NEAR_PI = 1e-3
#: rotation_log: a skew part (2 sin(angle)) at or below this counts as no turn, where
#: angle / (2 sin(angle)) is its limit 1/2.
TURNING_ABOVE = 1e-12
#: rotation_exp: below this angle [rad] its coefficients are their Taylor series.
SERIES_BELOW = 1e-8

#: The C text (sim/_rotations.c over native/_rotation.h), configured with the above.
_C = native.require(
    "sim._rotations",
    "configure",
    "exponential",
    "logarithm",
    "relative_logarithm",
    "to_quaternion",
    "to_rotation",
    "slerp",
    "nearest",
)
_C.configure(NEAR_PI, TURNING_ABOVE, SERIES_BELOW, SLERP_LINEAR)


def _rows(x, width: tuple[int, ...]) -> np.ndarray:
    """``x`` (..., *width) as float64 rows of shape ``width`` (a view where it can be).

    Raises:
        ValueError: ``x`` does not end in ``width``.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.shape[x.ndim - len(width) :] != width:
        raise ValueError(
            f"expected an array of shape (..., {', '.join(map(str, width))}), got {x.shape}"
        )
    return x.reshape((-1, *width))


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
    """(..., 3) rotation vectors to (..., 3, 3) matrices (Rodrigues):
    ``I + sin(t) / t K + (1 - cos(t)) / t^2 K^2`` with ``K = skew(rotvec)``, ``t = |rotvec|``
    (their series below :data:`SERIES_BELOW`)."""
    rows = _rows(rotvec, (3,))
    out = _C.exponential(rows, np.empty((len(rows), 3, 3)))
    return out.reshape(*np.shape(rotvec)[:-1], 3, 3)


def rotation_log(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 3) rotation vectors (axis * angle), the
    angle in [0, pi]: the inverse of :func:`rotation_exp`.

    The angle is atan2(|vee|, trace - 1) of the skew part vee = 2 sin(angle) axis,
    exact over [0, pi]; the axis is vee's direction, except within :data:`NEAR_PI` of a half turn,
    where vee vanishes and the axis comes from the quaternion (Eigen's ``AngleAxisd``).
    """
    rows = _rows(R, (3, 3))
    out = _C.logarithm(rows, np.empty((len(rows), 3)))
    return out.reshape(*np.shape(R)[:-2], 3)


def relative_rotation_log(
    R_a: np.ndarray, R_b: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """(n, 3) ``rotation_log(R_a^T R_b)`` of (n, 3, 3) pairs (the same n: no broadcasting).
    ``out``: an (n, 3) array to write the result into (and return)."""
    R_a, R_b = _rows(R_a, (3, 3)), _rows(R_b, (3, 3))
    if out is None:
        out = np.empty((len(R_a), 3))
    return _C.relative_logarithm(R_a, R_b, out)


def rotation_to_quaternion(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 4) quaternions (w, x, y, z), Shepperd's method.

    Eigen's conversion (``Quaternion(const Matrix3&)``): if the trace is positive,
    ``w`` is computed first (then ``w > 0``); otherwise the component of the
    largest diagonal entry (first one on ties), so the square root is always
    taken of a number >= 1 and nothing is divided by a small value.
    """
    rows = _rows(R, (3, 3))
    out = _C.to_quaternion(rows, np.empty((len(rows), 4)))
    return out.reshape(*np.shape(R)[:-2], 4)


def quaternion_to_rotation(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) to (..., 3, 3) rotation matrices, entry by
    entry as Eigen's ``toRotationMatrix`` (e.g. ``R[0, 0] = 1 - (2yy + 2zz)``,
    ``R[0, 1] = 2xy - 2zw``)."""
    rows = _rows(q, (4,))
    out = _C.to_rotation(rows, np.empty((len(rows), 3, 3)))
    return out.reshape(*np.shape(q)[:-1], 3, 3)


def quaternion_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Eigen's ``q0.slerp(t, q1)``, (..., 4): along the shorter arc (``q1`` negated when
    the dot product is negative), linear in the coefficients once |q0 . q1| >= 1 - eps
    (:data:`SLERP_LINEAR`)."""
    q0, q1 = np.broadcast_arrays(np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64))
    lead = q0.shape[:-1]
    t = np.broadcast_to(np.asarray(t, dtype=np.float64), lead).reshape(-1)
    rows0, rows1 = q0.reshape(-1, 4), q1.reshape(-1, 4)
    out = _C.slerp(rows0, rows1, t, np.empty((len(rows0), 4)))
    return out.reshape(*lead, 4)


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the rotation nearest each nearly orthonormal matrix (its polar factor),
    e.g. a rotation rounded to float32 on the wire: three Newton-Schulz steps
    ``X <- X (3 I - X^T X) / 2``, which converge quadratically from a matrix within
    ~1e-3 of orthonormal (float32 rounding: 1e-7 -> below float64's rounding)."""
    rows = _rows(R, (3, 3))
    out = _C.nearest(rows, np.empty((len(rows), 3, 3)))
    return out.reshape(np.shape(R))


#: skew(k) flat, row-major, from [0, kx, ky, kz, -kx, -ky, -kz]: entries (0, 1), (0, 2),
#: (1, 0), (1, 2), (2, 0), (2, 1) are -kz, ky, kz, -kx, -ky, kx; the diagonal is zero.
_SKEW_FROM_PADDED = np.array([0, 6, 2, 3, 0, 4, 5, 1, 0])
