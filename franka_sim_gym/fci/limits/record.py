"""What the limit rules share: the no-error value, the log line's record, the interval.

The rules themselves (which rows trip, which one wins: docs/fci-behaviour.md "What is
checked, and what it latches") are each one text: the joint, safety and torque rules in C
(fci/limits/_joint.c), the Cartesian rules in fci/limits/cartesian.py.
"""

from __future__ import annotations

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


def interval(steps) -> np.ndarray | float:
    """(n, 1) differencing interval ``steps * dt`` [s] (or (1, 1) for a scalar ``steps``).

    (docs/fci-behaviour.md "The difference formulas"): the interval is the server's own count
    of published cycles since the command the history sits at, not an assumed
    millisecond. ``steps`` >= 1 is the caller's precondition.
    """
    if isinstance(steps, int | np.integer):  # one interval for every robot: a scalar is cheapest
        return float(steps) * DELTA_T
    return np.asarray(steps, dtype=np.float64).reshape(-1, 1) * DELTA_T
