"""Homogeneous transforms in the robot's wire convention (column-major 4x4, 16 values)."""

from __future__ import annotations

import numpy as np

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
    (docs/libfranka-client.md §9).

    Bottom row exactly [0, 0, 0, 1]; every row and column of the rotation block of
    unit norm within ``tol``. A non-finite pose fails.
    """
    bottom = (T[:, 3, 0] == 0.0) & (T[:, 3, 1] == 0.0) & (T[:, 3, 2] == 0.0) & (T[:, 3, 3] == 1.0)
    R = T[:, :3, :3]
    rows = np.abs(np.sqrt(np.einsum("nij,nij->ni", R, R)) - 1.0) <= tol
    cols = np.abs(np.sqrt(np.einsum("nij,nij->nj", R, R)) - 1.0) <= tol
    return bottom & rows.all(axis=1) & cols.all(axis=1) & np.isfinite(T).all(axis=(1, 2))


def is_homogeneous_wire(values: np.ndarray, tol: float = 1e-5) -> np.ndarray | None:
    """:func:`is_homogeneous` of (n, 16) column-major wire poses: None when every pose
    passes (the common case, so the caller needs no mask), else the (n,) verdict."""
    verdict = is_homogeneous(from_wire(values), tol)
    return None if np.count_nonzero(verdict) == len(verdict) else verdict


def is_homogeneous_transformation(values: np.ndarray, tol: float = 1e-5) -> bool:
    """:func:`is_homogeneous` of one column-major wire transform (16 values)."""
    return bool(is_homogeneous(from_wire(values)[None], tol)[0])
