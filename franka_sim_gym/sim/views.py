"""The arms' rows of MuJoCo's data arrays as views, where the layout allows.

MuJoCo lays the arms of a world out one after another, so arm i's entries of a data
array sit at evenly spaced rows; a strided view of them replaces a fancy-index copy on
every read and write of the 1 kHz path (sim/arm.py's joint arrays, sim/kinematics.py's
private MjData).
"""

from __future__ import annotations

import numpy as np


def strided_rows(array: np.ndarray, index: np.ndarray) -> np.ndarray | None:
    """``array[index]`` as a view when ``index`` (integer, any shape) steps evenly along
    each of its axes, else None. Rows of a MuJoCo data array stay put for its lifetime."""
    index = np.asarray(index, dtype=np.intp)
    if not array.flags.c_contiguous or index.size == 0:
        return None
    if index.min() < 0 or index.max() >= len(array):
        return None
    steps = []  # the step along each axis of the index, if constant
    for axis in range(index.ndim):
        if index.shape[axis] < 2:
            steps.append(0)
            continue
        diff = np.diff(index, axis=axis)
        if diff.flat[0] < 0 or not (diff == diff.flat[0]).all():
            return None
        steps.append(int(diff.flat[0]))

    def rows_of(a: np.ndarray) -> np.ndarray:
        return np.lib.stride_tricks.as_strided(
            a[int(index.flat[0]) :],
            shape=index.shape + a.shape[1:],
            strides=tuple(s * a.strides[0] for s in steps) + a.strides[1:],
        )

    # the same view of a probe of the same layout must select the rows the index names
    probe = np.arange(array.size, dtype=array.dtype).reshape(array.shape)
    if not np.array_equal(rows_of(probe), probe[index]):  # pragma: no cover - a layout error
        raise AssertionError("a strided view disagrees with its gather")
    return rows_of(array)
