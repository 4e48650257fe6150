"""Shared machinery of the limit rules: the precedence table, intervals, violation records.

Every rule function stacks its per-joint findings into one (n, rows, joints)
bool array — [i, k, j] means "row k of this generator's precedence table trips
on robot i's joint j" — reduces it over the joints, packs each robot's rows
into one byte and looks that up in a table mapping a row bitmask to the error
of the *first* row that is set (docs/fci-behaviour.md "What is checked, and what it latches":
"the first row whose condition trips is the error you get"). That keeps the
per-cycle path to a handful of numpy operations whatever the number of rows,
with no Python loop over robots or joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ERROR_NAMES
from ..tables import DELTA_T

#: The "no violation" value of every ``error`` array.
NO_ERROR = -1


@dataclass(frozen=True)
class Violation:
    """What robot i's latched error was about, for the log line.

    ``joint`` is the 0-based joint index (``-1`` when the signal is not per
    joint, e.g. the end-effector speed); :meth:`message` prints it 1-based,
    as our log lines (docs/fci-behaviour.md) and Franka's tables number joints 1-7.
    ``value`` is the offending (signed) value of ``signal``'s checked quantity,
    ``limit`` the bound it crossed (the magnitude for a symmetric ``|x| <=``
    limit; NaN for a non-finite command, which has no bound), ``check`` which
    row of the precedence table tripped.
    """

    error: int
    signal: str
    joint: int
    value: float
    limit: float
    unit: str
    check: str = ""

    def message(self) -> str:
        """The log line of docs/fci-behaviour.md "Checking is always on; aborting is opt-in", e.g.

        ``joint_motion_generator_velocity_discontinuity: q_c joint 4 = 294.395 rad/s^2,
        limit 9.999 rad/s^2 (acceleration)``.
        """
        where = f"{self.signal} joint {self.joint + 1}" if self.joint >= 0 else self.signal
        return (
            f"{ERROR_NAMES[self.error]}: {where} = {self.value:.6g} {self.unit}, "
            f"limit {self.limit:.6g} {self.unit} ({self.check})"
        )


@dataclass(frozen=True)
class Row:
    """One row of a precedence table, as :func:`describe_row` reports it (describe path only).

    Which joints trip is the check's mask; ``value`` against ``upper`` / ``lower``
    only ranks the tripped joints (largest excess first) and names the bound.
    """

    error: int
    check: str
    signal: str
    unit: str
    value: np.ndarray
    upper: np.ndarray | float
    lower: np.ndarray | float
    symmetric: bool = False


class Precedence:
    """First-row-wins selection over up to 8 rows, optionally gated by ``first``.

    ``codes[k]`` is the error of row k, rows in precedence order. Rows listed in
    ``first_only`` apply only where ``first`` is true, rows in ``later_only``
    only where it is false.
    """

    def __init__(
        self,
        codes: Sequence[int],
        first_only: Sequence[int] = (),
        later_only: Sequence[int] = (),
    ) -> None:
        k = len(codes)
        if not 0 < k <= 8:
            raise ValueError("between 1 and 8 rows")
        every = (1 << k) - 1
        allowed = (
            every & ~sum(1 << r for r in first_only),  # first == False
            every & ~sum(1 << r for r in later_only),  # first == True
        )
        lut = np.full((2, 1 << k), NO_ERROR, dtype=np.int64)
        for first, gate in enumerate(allowed):
            for bits in range(1, 1 << k):
                live = bits & gate
                if live:
                    lut[first, bits] = codes[(live & -live).bit_length() - 1]
        lut.setflags(write=False)
        self.allowed = allowed
        self.lut = lut

    def select(self, tripped: np.ndarray, first: np.ndarray) -> np.ndarray:
        """(n,) int64 error from (n, rows, m) ``tripped`` and (n,) bool ``first``."""
        rows = np.packbits(tripped.any(axis=2), axis=1, bitorder="little")[:, 0]
        return self.lut[first.view(np.uint8), rows]

    def first_row(self, tripped: np.ndarray, first: bool) -> int | None:
        """Index of the row that wins for one robot's (rows, m) ``tripped``, or None."""
        live = int(np.packbits(tripped.any(axis=1), bitorder="little")[0])
        live &= self.allowed[int(first)]
        return (live & -live).bit_length() - 1 if live else None


def stack(*masks: np.ndarray) -> np.ndarray:
    """(n, rows, m) bool from the rows' (n, m) per-joint masks, in precedence order."""
    return np.concatenate(masks, axis=1).reshape(-1, len(masks), masks[0].shape[-1])


def as_bool(first) -> np.ndarray:
    """``first`` as a bool ndarray ((n,) or 0-d), so that ``~`` and ``view`` behave."""
    return np.asarray(first, dtype=bool)


def interval(steps) -> np.ndarray | float:
    """(n, 1) differencing interval ``steps * dt`` [s] (or (1, 1) for a scalar ``steps``).

    (docs/fci-behaviour.md "The difference formulas"): the interval is the server's own count
    of published cycles since the command the history sits at, not an assumed
    millisecond. ``steps`` >= 1 is the caller's precondition.
    """
    if isinstance(steps, int | np.integer):  # one interval for every robot: a scalar is cheapest
        return float(steps) * DELTA_T
    return np.asarray(steps, dtype=np.float64).reshape(-1, 1) * DELTA_T


def robot_row(x, i: int):
    """Robot i's slice of a batched argument, keeping the leading axis (scalars pass through)."""
    a = np.asarray(x)
    return a if a.ndim == 0 else a[i : i + 1]


def describe_row(row: Row, tripped: np.ndarray) -> Violation:
    """The worst joint among those where ``row`` trips (``tripped``: one robot's (m,) mask)."""
    value = np.asarray(row.value, dtype=np.float64).reshape(-1)
    upper = np.broadcast_to(np.asarray(row.upper, dtype=np.float64), (1, value.size)).reshape(-1)
    lower = np.broadcast_to(np.asarray(row.lower, dtype=np.float64), (1, value.size)).reshape(-1)
    tripped = np.asarray(tripped, dtype=bool).reshape(-1)
    bad = tripped & ~np.isfinite(value)
    if bad.any():
        # NaN / inf has no distance to a bound (docs/fci-behaviour.md: a non-finite command is
        # "the limits violation of the generator"): name the first such joint.
        j = int(np.flatnonzero(bad)[0])
        nan = float("nan")
        return Violation(row.error, row.signal, j, float(value[j]), nan, row.unit, "non-finite")
    excess = np.where(tripped, np.maximum(value - upper, lower - value), -np.inf)
    j = int(np.argmax(excess))
    above = value[j] - upper[j] >= lower[j] - value[j]
    limit = upper[j] if (above or row.symmetric) else lower[j]
    return Violation(row.error, row.signal, j, float(value[j]), float(limit), row.unit, row.check)
