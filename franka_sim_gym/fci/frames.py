"""Homogeneous transforms in the robot's wire convention (column-major 4x4, 16 values)."""

from __future__ import annotations

import numpy as np

IDENTITY16 = np.eye(4).reshape(16)
IDENTITY16.setflags(write=False)


def to_wire(T: np.ndarray) -> np.ndarray:
    """(..., 4, 4) row-major matrices to (..., 16) column-major wire arrays."""
    return np.swapaxes(T, -1, -2).reshape(*T.shape[:-2], 16)


def from_wire(values: np.ndarray) -> np.ndarray:
    """(..., 16) column-major wire arrays to (..., 4, 4) row-major matrices."""
    values = np.asarray(values, dtype=np.float64)
    return np.swapaxes(values.reshape(*values.shape[:-1], 4, 4), -1, -2)


def is_homogeneous_transformation(values: np.ndarray, tol: float = 1e-5) -> bool:
    """libfranka's isHomogeneousTransformation (libfranka-client-behaviour.md §9).

    Column-major elements 3, 7, 11 exactly 0 and 15 exactly 1; every row and
    column of the rotation block of unit norm within ``tol``.
    """
    v = np.asarray(values, dtype=np.float64).reshape(16)
    if not np.all(np.isfinite(v)):
        return False
    if v[3] != 0.0 or v[7] != 0.0 or v[11] != 0.0 or v[15] != 1.0:
        return False
    R = from_wire(v)[:3, :3]
    return bool(
        np.all(np.abs(np.linalg.norm(R, axis=0) - 1.0) <= tol)
        and np.all(np.abs(np.linalg.norm(R, axis=1) - 1.0) <= tol)
    )


def elbow_of(q: np.ndarray) -> np.ndarray:
    """The measured elbow (q3, sign(q4)) of (n, 7) joint positions, shape (n, 2).

    Seed "RobotState fields": elbow is a reading of q: the redundancy angle is
    joint 3 and the branch flag the sign of joint 4 (always -1 inside the FR3's
    joint-4 range). sign(0) is taken as +1 so the flag is always +-1.
    """
    flag = np.where(q[:, 3] < 0.0, -1.0, 1.0)
    return np.stack([q[:, 2], flag], axis=1)
