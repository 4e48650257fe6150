"""Cycle accounting: which cycles were answered in time, in cycle space, never wall clock.

docs/fci-behaviour.md "The cycle contract" and "What the sim does with a lost cycle":
control_command_success_rate is the fraction of the last 100 cycles answered
in time (while the window fills, the divisor is what it holds), 0.0 between
motions; lost_run counts consecutive unanswered cycles.

A motion's accounting opens with the first command the client sends: libfranka
sends nothing while it waits for the mode switch and on the first cycle of its
loop (docs/libfranka-client.md §5), and the robot holds the start pose
until then.
"""

from __future__ import annotations

import numpy as np

from .. import native
from .tables import MAX_LOST_CYCLES, SUCCESS_RATE_WINDOW

#: the close of a cycle's one text (fci/_accounting.c)
_RULES = native.require("fci._accounting", "close_cycle")

_NO_MOTION = np.iinfo(np.uint64).max


class CycleAccounting:
    """Per-robot success-rate window and lost-cycle run."""

    def __init__(self, n: int, window: int = SUCCESS_RATE_WINDOW) -> None:
        self.n = n
        self.window = window
        self._ring = np.zeros((n, window), dtype=bool)
        self._pos = 0  # one ring position for all robots; each robot's ring is cleared per motion
        self._counted = np.zeros(n, dtype=np.int64)
        self._answered_sum = np.zeros(n, dtype=np.int64)
        #: a command answering the open cycle has arrived
        self.answered = np.zeros(n, dtype=bool)
        #: the first command of the motion has arrived (accounting is open)
        self.started = np.zeros(n, dtype=bool)
        #: consecutive unanswered cycles of the running motion
        self.lost_run = np.zeros(n, dtype=np.int64)
        #: the longest such run, and all cycles lost, in the running motion
        self.longest_lost_run = np.zeros(n, dtype=np.int64)
        self.lost_total = np.zeros(n, dtype=np.int64)
        #: the first message_id a command of the running motion may echo
        self.motion_first_id = np.full(n, _NO_MOTION, dtype=np.uint64)
        self._rate = np.zeros(n)

    def start_motion(self, i: int, last_published_id: int) -> None:
        """A Move started; commands echoing states from now on belong to it."""
        self.stop_motion(i)
        self.motion_first_id[i] = last_published_id

    def stop_motion(self, i: int) -> None:
        """The motion ended: the window empties and the rate reads 0.0."""
        self._ring[i] = False
        self._counted[i] = 0
        self._answered_sum[i] = 0
        self.answered[i] = False
        self.started[i] = False
        self.lost_run[i] = 0
        self.longest_lost_run[i] = 0
        self.lost_total[i] = 0
        self.motion_first_id[i] = _NO_MOTION
        self._rate[i] = 0.0

    def motion_summary(self, i: int) -> tuple[int, int, int]:
        """(cycles counted, cycles lost, longest lost run) of robot i's running motion."""
        return (
            int(self._counted[i]),
            int(self.lost_total[i]),
            int(self.longest_lost_run[i]),
        )

    def rearm(self, i: int) -> None:
        """AutomaticErrorRecovery re-arms the lost-cycle bound."""
        self.lost_run[i] = 0

    def close_cycle(self) -> int:
        """Close the open cycle for every robot whose accounting is open: one C call
        (fci/_accounting.c, the rule's only text). Returns how many robots have lost
        MAX_LOST_CYCLES in a row or more (the communication constraints' bound)."""
        pos = self._pos
        self._pos = (pos + 1) % self.window
        return _RULES.close_cycle(
            self.answered, self.started, self._ring, pos, self._answered_sum, self._counted,
            self.lost_total, self.lost_run, self.longest_lost_run, self._rate,
            self.window, MAX_LOST_CYCLES,
        )  # fmt: skip

    def success_rate(self) -> np.ndarray:
        """control_command_success_rate per robot: answered / cycles held by the window."""
        return self._rate
