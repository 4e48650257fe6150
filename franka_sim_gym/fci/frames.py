"""Homogeneous transforms in the robot's wire convention (column-major 4x4, 16 values)."""

from __future__ import annotations

import numpy as np

from .. import native

IDENTITY16 = np.eye(4).reshape(16)
IDENTITY16.setflags(write=False)

#: libfranka's isHomogeneousTransformation, its one text (native/_homogeneous.h, called
#: on a batch by fci/_frames.c).
_C = native.require("fci._frames", "homogeneous")

#: isHomogeneousTransformation's tolerance on the rotation's row and column norms
#: (libfranka control_tools.h: kOrthonormalThreshold = 1e-5).
HOMOGENEOUS_TOL = 1e-5


def to_wire(T: np.ndarray) -> np.ndarray:
    """(..., 4, 4) row-major matrices to (..., 16) column-major wire arrays."""
    # (the array's own methods: np.swapaxes's dispatch costs as much as the copy here)
    return T.swapaxes(-1, -2).reshape(T.shape[:-2] + (16,))


def from_wire(values: np.ndarray) -> np.ndarray:
    """(..., 16) column-major wire arrays to (..., 4, 4) row-major matrices."""
    values = np.asarray(values, dtype=np.float64)
    return np.swapaxes(values.reshape(*values.shape[:-1], 4, 4), -1, -2)


def _verdict(T: np.ndarray, tol: float) -> tuple[np.ndarray, int]:
    """(the (n,) verdict, how many passed) of (n, 4, 4) row-major poses (any strides)."""
    T = np.asarray(T, dtype=np.float64)
    out = np.empty(len(T), dtype=np.uint8)
    passed = _C.homogeneous(T, float(tol), out)
    return out.view(bool), passed


def is_homogeneous(T: np.ndarray, tol: float = HOMOGENEOUS_TOL) -> np.ndarray:
    """(n,) libfranka's isHomogeneousTransformation on (n, 4, 4) row-major poses
    (docs/libfranka-client.md §9).

    Bottom row exactly [0, 0, 0, 1]; every row and column of the rotation block of
    unit norm within ``tol``. A non-finite pose fails.
    """
    return _verdict(T, tol)[0]


def is_homogeneous_transformation(values: np.ndarray, tol: float = HOMOGENEOUS_TOL) -> bool:
    """:func:`is_homogeneous` of one column-major wire transform (16 values)."""
    return bool(_verdict(from_wire(values)[None], tol)[0][0])
