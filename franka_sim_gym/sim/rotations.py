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
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "NEAR_PI",
    "SERIES_BELOW",
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
_SLERP_LINEAR = 1.0 - float(np.finfo(np.float64).eps)

#: Within this of a half turn [rad] the skew part of R, 2 sin(angle) axis, has too few
#: significant bits for the axis (its rounding is ~1e-16 absolute): rotation_log takes
#: the axis from the quaternion there (Shepperd's method, exact up to pi).
NEAR_PI = 1e-3
#: rotation_log: a skew part (2 sin(angle)) at or below this counts as no turn, where
#: angle / (2 sin(angle)) is its limit 1/2.
TURNING_ABOVE = 1e-12
#: rotation_exp: below this angle [rad] its coefficients are their Taylor series.
SERIES_BELOW = 1e-8


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
    angle = np.sqrt(np.add.reduce(rotvec * rotvec, axis=-1))
    small = angle < SERIES_BELOW
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle**2 / 6.0, np.sin(angle) / safe)
    b = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(angle)) / safe**2)
    K = skew(rotvec)
    return _EYE3 + a[..., None, None] * K + b[..., None, None] * (K @ K)


def rotation_log(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 3) rotation vectors (axis * angle), the
    angle in [0, pi]: the inverse of :func:`rotation_exp`.

    The angle is atan2(|vee|, trace - 1) of the skew part vee = 2 sin(angle) axis,
    exact over [0, pi]; the axis is vee's direction, except within :data:`NEAR_PI` of a half turn,
    where vee vanishes and the axis comes from the quaternion (Eigen's ``AngleAxisd``).
    """
    flat = R.reshape(*R.shape[:-2], 9)
    # (R21 - R12, R02 - R20, R10 - R01): one gather each side instead of three stacks.
    vee = flat[..., _VEE_PLUS] - flat[..., _VEE_MINUS]
    two_sin = np.sqrt(np.einsum("...i,...i->...", vee, vee))
    angle = np.arctan2(two_sin, flat[..., 0] + flat[..., 4] + flat[..., 8] - 1.0)
    _scale_vee(vee, two_sin, angle)
    near_pi = np.pi - angle < NEAR_PI
    if np.count_nonzero(near_pi):
        vee[near_pi] = _quaternion_log(rotation_to_quaternion(R[near_pi]))
    return vee


def relative_rotation_log(
    R_a: np.ndarray, R_b: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """(n, 3) ``rotation_log(R_a^T R_b)`` of (n, 3, 3) pairs, the product's skew part and
    trace taken as contractions of R_a with R_b (one call each). ``out``: an (n, 3) array
    to write the result into (and return)."""
    vee = np.einsum("iab,nka,nkb->ni", _NEG_LEVI_CIVITA, R_a, R_b, out=out)
    two_cos = np.einsum("nka,nka->n", R_a, R_b) - 1.0
    two_sin = np.sqrt(np.einsum("ni,ni->n", vee, vee))
    angle = np.arctan2(two_sin, two_cos)
    _scale_vee(vee, two_sin, angle)
    near_pi = np.pi - angle < NEAR_PI
    if np.count_nonzero(near_pi):  # the skew part vanishes: rotation_log's branch
        vee[near_pi] = rotation_log(R_a[near_pi].transpose(0, 2, 1) @ R_b[near_pi])
    return vee


def _scale_vee(vee: np.ndarray, two_sin: np.ndarray, angle: np.ndarray) -> None:
    """vee (2 sin(angle) axis) *= angle / (2 sin(angle)), in place (1/2 as angle -> 0)."""
    turning = two_sin > TURNING_ABOVE
    vee *= np.where(turning, angle / np.where(turning, two_sin, 1.0), 0.5)[..., None]


def _quaternion_log(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions to (..., 3) axis * angle, angle ``2 atan2(|v|, |w|)`` in
    [0, pi], axis ``v / |v|`` with the sign of ``w``; the identity gives zero."""
    w, vec = q[..., 0], q[..., 1:]
    n = np.sqrt(np.einsum("...i,...i->...", vec, vec))
    turning = n > 0.0
    angle = 2.0 * np.arctan2(n, np.abs(w))
    axis = vec / np.where(w < 0.0, -n, np.where(turning, n, 1.0))[..., None]
    return np.where(turning[..., None], axis * angle[..., None], 0.0)


def rotation_to_quaternion(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 4) quaternions (w, x, y, z), Shepperd's method.

    Eigen's conversion (``Quaternion(const Matrix3&)``): if the trace is positive,
    ``w`` is computed first (then ``w > 0``); otherwise the component of the
    largest diagonal entry (first one on ties), so the square root is always
    taken of a number >= 1 and nothing is divided by a small value. Row ``b`` of
    the symmetric matrix ``K`` (:data:`_SHEPPERD_ROWS`) is ``4 q_b q``; the chosen
    row divided by ``4 q_b = 2 sqrt(K[b, b])`` is the quaternion.
    """
    lead = R.shape[:-2]
    flat = R.reshape(-1, 9)
    trace = flat[:, 0] + flat[:, 4] + flat[:, 8]
    # row 0 where the trace is positive, else the largest diagonal entry's (first on ties)
    branch = np.where(trace > 0.0, 0, np.argmax(flat[:, ::4], axis=1) + 1)
    q = np.empty((len(flat), 4))
    for b in np.unique(branch).tolist():
        rows = branch == b
        q[rows] = _quaternion_from_row(flat[rows], b, trace[rows])
    return q.reshape(*lead, 4)


def _quaternion_from_row(flat: np.ndarray, b: int, trace: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions from row ``b`` of Shepperd's ``K`` of (n, 9) row-major rotations.

    The diagonal entry ``K[b, b] = 4 q_b^2`` is ``trace + 1`` (b = 0) or, for b = 1, 2, 3,
    ``1 + 2 m_bb - trace`` evaluated as ``m_bb - m_b'b' - m_b''b'' + 1``; the other three
    entries of the row are skew differences or symmetric sums of R (:data:`_SHEPPERD_ROWS`).
    """
    if b == 0:
        k_bb = trace + 1.0
    else:
        d0, d1, d2 = (flat[:, 4 * ((b - 1 + k) % 3)] for k in range(3))
        k_bb = d0 - d1 - d2 + 1.0
    others, plus, minus, sign = _SHEPPERD_ROWS[b]
    t = np.sqrt(k_bb)
    q = np.empty((len(flat), 4))
    q[:, b] = 0.5 * t
    q[:, others] = (flat[:, plus] + sign * flat[:, minus]) * (0.5 / t)[:, None]
    return q


def quaternion_to_rotation(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) to (..., 3, 3) rotation matrices.

    Entry by entry ``R[i, j] = [1 -] (P[a] +- P[b])`` over the products ``P[k, l] =
    (2 q_k) q_l`` (:data:`_QUATERNION_TERMS`): e.g. ``R[0, 0] = 1 - (2yy + 2zz)``,
    ``R[0, 1] = 2xy - 2zw``, as Eigen's ``toRotationMatrix`` -- in a few array calls.
    """
    lead = q.shape[:-1]
    P = ((2.0 * q)[..., :, None] * q[..., None, :]).reshape(*lead, 16)
    R = P[..., _QUATERNION_TERMS[0]] + _QUATERNION_TERMS[2] * P[..., _QUATERNION_TERMS[1]]
    R[..., ::4] = 1.0 - R[..., ::4]
    return R.reshape(*lead, 3, 3)


def quaternion_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Eigen's ``q0.slerp(t, q1)``, (..., 4): along the shorter arc (``q1`` negated when
    the dot product is negative), linear in the coefficients once |q0 . q1| >= 1 - eps."""
    d = np.einsum("...i,...i->...", q0, q1)
    abs_d = np.abs(d)
    linear = abs_d >= _SLERP_LINEAR
    theta = np.arccos(np.minimum(abs_d, 1.0))
    sin_theta = np.where(linear, 1.0, np.sin(theta))
    s0 = np.where(linear, 1.0 - t, np.sin((1.0 - t) * theta) / sin_theta)
    s1 = np.where(linear, t, np.sin(t * theta) / sin_theta)
    s1 = np.where(d < 0.0, -s1, s1)
    return s0[..., None] * q0 + s1[..., None] * q1


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the rotation nearest each nearly orthonormal matrix (its polar factor),
    e.g. a rotation rounded to float32 on the wire: three Newton-Schulz steps
    ``X <- X (3 I - X^T X) / 2``, which converge quadratically from a matrix within
    ~1e-3 of orthonormal (float32 rounding: 1e-7 -> below float64's rounding)."""
    X = np.array(R, dtype=np.float64)
    for _ in range(3):
        X = 0.5 * (X @ (3.0 * _EYE3 - np.swapaxes(X, -1, -2) @ X))
    return X


_EYE3 = np.eye(3)
_EYE3.setflags(write=False)

#: rotation_log's skew part in the flat row-major matrix: entries 7 - 5, 2 - 6, 3 - 1.
_VEE_PLUS = np.array([7, 2, 3])
_VEE_MINUS = np.array([5, 6, 1])
#: skew(k) flat, row-major, from [0, kx, ky, kz, -kx, -ky, -kz]: entries (0, 1), (0, 2),
#: (1, 0), (1, 2), (2, 0), (2, 1) are -kz, ky, kz, -kx, -ky, kx; the diagonal is zero.
_SKEW_FROM_PADDED = np.array([0, 6, 2, 3, 0, 4, 5, 1, 0])

#: The Levi-Civita symbol: (a x b)_i = eps_iab a_a b_b.
LEVI_CIVITA = np.zeros((3, 3, 3))
LEVI_CIVITA[0, 1, 2] = LEVI_CIVITA[1, 2, 0] = LEVI_CIVITA[2, 0, 1] = 1.0
LEVI_CIVITA[0, 2, 1] = LEVI_CIVITA[2, 1, 0] = LEVI_CIVITA[1, 0, 2] = -1.0
LEVI_CIVITA.setflags(write=False)

#: vee(M - M^T) of M = R_a^T R_b is -eps_iab R_a[k, a] R_b[k, b].
_NEG_LEVI_CIVITA = -LEVI_CIVITA

#: Row b of Shepperd's symmetric K, off the diagonal: the quaternion components it
#: yields, and each entry as flat[plus] + sign * flat[minus] over the row-major R --
#: K[0, 1:] = (R21 - R12, R02 - R20, R10 - R01), K[1, 2] = R01 + R10,
#: K[1, 3] = R02 + R20, K[2, 3] = R12 + R21.
_SHEPPERD_ROWS = tuple(
    (np.array(others), np.array(plus), np.array(minus), np.array(sign))
    for others, plus, minus, sign in (
        ((1, 2, 3), (7, 2, 3), (5, 6, 1), (-1.0, -1.0, -1.0)),
        ((0, 2, 3), (7, 1, 2), (5, 3, 6), (-1.0, 1.0, 1.0)),
        ((0, 1, 3), (2, 1, 5), (6, 3, 7), (-1.0, 1.0, 1.0)),
        ((0, 1, 2), (3, 2, 5), (1, 6, 7), (-1.0, 1.0, 1.0)),
    )
)

#: quaternion_to_rotation: for each entry of R (row-major), the flat indices a and b
#: into the products P (index 4k + l for (2 q_k) q_l, q = (w, x, y, z)) and the sign
#: of P[b]; the diagonal entries are then taken from 1.
_QUATERNION_TERMS = (
    np.array([10, 6, 7, 6, 5, 11, 7, 11, 5]),  # yy, xy, xz; xy, xx, yz; xz, yz, xx
    np.array([15, 12, 8, 12, 15, 4, 8, 4, 10]),  # zz, zw, yw; zw, zz, xw; yw, xw, yy
    np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0]),
)
