"""Rows of MuJoCo's data arrays as views, and every robot's rows of its own MjData.

Where a world holds several arms (sim/kinematics.py's stacked world), MuJoCo lays them
out one after another, so arm i's entries of a data array sit at evenly spaced rows: a
strided view of them replaces a fancy-index copy on every read and write of the 1 kHz
path (:func:`strided_rows`). Where every robot steps its own MjData of one model
(sim/arm.py), :class:`ArmRows` gathers robot i's rows of each into one (n, ...) array
and writes rows back, and :class:`Gathering` refreshes several of them in one call.
"""

from __future__ import annotations

import numpy as np

from .. import native

#: ArmRows' loops over the robots (sim/_rows.c: copies, no rule; required like every C
#: module, issue 38: no switch). Rows a C loop cannot take (not evenly spaced, not
#: float64) are copied by numpy, the same bits.
ROWS_KERNEL = native.require("sim._rows", "Gathers", "scatter")


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


class ArmRows:
    """One slice of every robot's MjData array: robot i's ``array[index]`` of its own
    MjData, gathered into one (n, ...) array and written back per robot.

    Args:
        arrays: robot i's MuJoCo data array (e.g. ``datas[i].qpos``), one per robot.
        index: the slice's rows (the same in every robot's MjData: one model); an int
            gives rows of that one entry's shape.

    ``out`` is the gathered array, refreshed in place by :meth:`gather` (so a reference
    to it reads like a live view after every gather).
    """

    def __init__(self, arrays: list[np.ndarray], index) -> None:
        self.arrays = arrays
        self.index = index = np.asarray(index, dtype=np.intp)
        flat = index.reshape(-1) if index.ndim else index.reshape(1)
        views = [strided_rows(a, flat) for a in arrays]
        shape = arrays[0][index].shape
        #: robot i's rows as a view of its MjData (None: the rows are not evenly spaced)
        self.views = None
        if all(v is not None for v in views):
            shaped = [v.reshape(shape) for v in views]
            if all(np.shares_memory(v, a) for v, a in zip(shaped, arrays, strict=True)):
                self.views = shaped
        self.out = np.empty((len(arrays), *shape), dtype=arrays[0].dtype)
        # the rows as the C loops take them: contiguous float64 views, or None
        self._sources = None
        if (
            self.views is not None
            and self.out.dtype == np.float64
            and all(v.flags.c_contiguous for v in self.views)
        ):
            self._sources = tuple(self.views)
        # the copies planned once (their buffers held): a gather is then one call
        self._plan = None if self._sources is None else ROWS_KERNEL.Gathers(self.pairs())

    def pairs(self) -> tuple[tuple[tuple[np.ndarray, ...], np.ndarray], ...]:
        """The (sources, out) pair sim/_rows.c's ``Gathers`` copies (empty where the C
        loop does not apply: rows not evenly spaced, not float64)."""
        return () if self._sources is None else ((self._sources, self.out),)

    def gather(self) -> np.ndarray:
        """``out`` refreshed from every robot's MjData."""
        out = self.out
        if self._plan is not None:
            self._plan.gather()
        elif self.views is not None:
            for i, view in enumerate(self.views):
                out[i] = view
        else:
            index = self.index
            for i, array in enumerate(self.arrays):
                out[i] = array[index]
        return out

    def get(self, i: int) -> np.ndarray:
        """Robot i's rows (a view where the rows are evenly spaced, else a copy)."""
        return self.views[i] if self.views is not None else self.arrays[i][self.index]

    def set(self, i: int, value) -> None:
        """Write robot i's rows of its MjData."""
        if self.views is not None:
            self.views[i][...] = value
        else:
            self.arrays[i][self.index] = value

    def scatter(self, values: np.ndarray, arms=None) -> None:
        """Write row k of ``values`` into robot ``arms[k]``'s MjData (every robot in order
        when ``arms`` is None)."""
        if self._sources is not None:
            values = np.ascontiguousarray(values, dtype=np.float64)
            rows = None if arms is None else np.ascontiguousarray(arms, dtype=np.int64)
            ROWS_KERNEL.scatter(values, self._sources, rows)
            return
        rows = range(len(self.arrays)) if arms is None else np.asarray(arms).tolist()
        for k, i in enumerate(rows):
            self.set(i, values[k])


class Gathering:
    """Several :class:`ArmRows` refreshed together: one C call copying all of them where
    every one of them takes sim/_rows.c's loop, else each one's gather.

    Args:
        rows: the slices, gathered in this order.
    """

    def __init__(self, rows) -> None:
        self.rows: tuple[ArmRows, ...] = tuple(rows)
        pairs = tuple(pair for r in self.rows for pair in r.pairs())
        self._plan = None
        if len(pairs) == len(self.rows):
            self._plan = ROWS_KERNEL.Gathers(pairs)

    def gather(self) -> None:
        """Every slice's ``out`` refreshed from every robot's MjData."""
        if self._plan is not None:
            self._plan.gather()
        else:
            for rows in self.rows:
                rows.gather()
