"""Homogeneous transforms in the robot's wire convention (column-major 4x4, 16 values)."""

from __future__ import annotations

import numpy as np

from .. import native
from ._fast import count_nonzero

#: fci/_cartesian_rules.c (its homogeneous_quick), or None: the numpy quick test
_KERNEL = native.load("fci._cartesian_rules")

IDENTITY16 = np.eye(4).reshape(16)
IDENTITY16.setflags(write=False)


def to_wire(T: np.ndarray) -> np.ndarray:
    """(..., 4, 4) row-major matrices to (..., 16) column-major wire arrays."""
    # (the array's own methods: np.swapaxes's dispatch costs as much as the copy here)
    return T.swapaxes(-1, -2).reshape(T.shape[:-2] + (16,))


def from_wire(values: np.ndarray) -> np.ndarray:
    """(..., 16) column-major wire arrays to (..., 4, 4) row-major matrices."""
    values = np.asarray(values, dtype=np.float64)
    return np.swapaxes(values.reshape(*values.shape[:-1], 4, 4), -1, -2)


def is_homogeneous(T: np.ndarray, tol: float = 1e-5) -> np.ndarray:
    """(n,) libfranka's isHomogeneousTransformation on (n, 4, 4) row-major poses
    (libfranka-client-behaviour.md §9).

    Bottom row exactly [0, 0, 0, 1]; every row and column of the rotation block of
    unit norm within ``tol``. A non-finite pose fails.
    """
    bottom = (T[:, 3, 0] == 0.0) & (T[:, 3, 1] == 0.0) & (T[:, 3, 2] == 0.0) & (T[:, 3, 3] == 1.0)
    R = T[:, :3, :3]
    rows = np.abs(np.sqrt(np.einsum("nij,nij->ni", R, R)) - 1.0) <= tol
    cols = np.abs(np.sqrt(np.einsum("nij,nij->nj", R, R)) - 1.0) <= tol
    return bottom & rows.all(axis=1) & cols.all(axis=1) & np.isfinite(T).all(axis=(1, 2))


def is_homogeneous_wire(values: np.ndarray, tol: float = 1e-5) -> np.ndarray | None:
    """:func:`is_homogeneous` of (n, 16) column-major wire poses, for the 1 kHz path.

    Returns None when every pose passes; otherwise the (n,) verdict of
    :func:`is_homogeneous`. The quick test accepts only squared norms well inside
    the band (half the tolerance), so a pose it passes passes the exact test too;
    anything nearer the edge, or failing, is judged by the exact test.
    """
    lo, hi = _QUICK_BAND if tol == 1e-5 else _quick_band(tol)
    if _quick_test(values, lo, hi):
        return None
    return is_homogeneous(from_wire(values), tol)


def _quick_test_numpy(values: np.ndarray, lo: float, hi: float) -> bool:
    """Whether every (n, 16) wire pose is finite, has the bottom row [0, 0, 0, 1] and
    every row's and column's squared norm strictly inside (lo, hi) (the reference)."""
    n = len(values)
    if count_nonzero(np.isfinite(values)) != 16 * n:  # (and no inf * 0 in the product below)
        return False
    # Row and column norms alike (the wire holds R transposed: the set is the same).
    norms2 = np.square(values.reshape(n, 4, 4)[:, :3, :3]).reshape(n, 9) @ _ROW_COL_SUMS
    return bool(
        count_nonzero((norms2 > lo) & (norms2 < hi)) == 6 * n
        and count_nonzero(values[:, 3::4] == _BOTTOM) == 4 * n
    )


def _quick_test_kernel(values: np.ndarray, lo: float, hi: float) -> bool:
    """:func:`_quick_test_numpy` in one C call (its sums may round differently in the last
    bit, far inside the half-tolerance margin: the verdicts are the same)."""
    if type(values) is np.ndarray and values.dtype == np.float64 and values.ndim == 2:
        return _KERNEL.homogeneous_quick(values, lo, hi)
    return _quick_test_numpy(values, lo, hi)


_quick_test = _quick_test_numpy if _KERNEL is None else _quick_test_kernel


#: (9, 6): a flat 3x3 block's squared entries to its three row sums and three column sums.
_ROW_COL_SUMS = np.zeros((9, 6))
for _r in range(3):
    for _c in range(3):
        _ROW_COL_SUMS[3 * _r + _c, _r] = _ROW_COL_SUMS[3 * _r + _c, 3 + _c] = 1.0
#: The bottom row [0, 0, 0, 1] in the column-major wire array (slots 3, 7, 11, 15).
_BOTTOM = np.array([0.0, 0.0, 0.0, 1.0])


def _quick_band(tol: float) -> tuple[float, float]:
    """Squared norms strictly inside |norm - 1| <= tol / 2 (so inside the exact band)."""
    return (1.0 - 0.5 * tol) ** 2, (1.0 + 0.5 * tol) ** 2


_QUICK_BAND = _quick_band(1e-5)


def is_homogeneous_transformation(values: np.ndarray, tol: float = 1e-5) -> bool:
    """:func:`is_homogeneous` of one column-major wire transform (16 values)."""
    return bool(is_homogeneous(from_wire(values)[None], tol)[0])
