"""Cycle accounting: which cycles were answered in time, in cycle space, never wall clock.

Seed "The cycle contract" and "What the sim does with a lost cycle":
control_command_success_rate is the fraction of the last 100 cycles answered
in time (while the window fills, the divisor is what it holds), 0.0 between
motions; lost_run counts consecutive unanswered cycles.

A motion's accounting opens with the first command the client sends: libfranka
sends nothing while it waits for the mode switch and on the first cycle of its
loop (libfranka-client-behaviour.md §5), and the robot holds the start pose
until then.
"""

from __future__ import annotations

import numpy as np

from .tables import SUCCESS_RATE_WINDOW


class CycleAccounting:
    """Per-robot success-rate window and lost-cycle run."""

    def __init__(self, n: int, window: int = SUCCESS_RATE_WINDOW) -> None:
        self.window = window
        self._ring = np.zeros((n, window), dtype=bool)
        self._pos = 0  # all robots share the ring position; fill counts are per robot
        self._filled = np.zeros(n, dtype=np.int64)
        self._answered_sum = np.zeros(n, dtype=np.int64)
        self._answered = np.zeros(n, dtype=bool)
        #: the first command of the motion has arrived (accounting is open)
        self.started = np.zeros(n, dtype=bool)
        #: consecutive unanswered cycles of the running motion
        self.lost_run = np.zeros(n, dtype=np.int64)
        #: the longest such run in the running motion
        self.longest_lost_run = np.zeros(n, dtype=np.int64)
        #: cycles lost in the running motion
        self.lost_total = np.zeros(n, dtype=np.int64)
        #: the first message_id a command of the running motion may echo
        self.motion_first_id = np.full(n, np.iinfo(np.uint64).max, dtype=np.uint64)

    def start_motion(self, i: int, last_published_id: int) -> None:
        """A Move started; commands echoing states from now on belong to it."""
        self.stop_motion(i)
        self.motion_first_id[i] = last_published_id

    def stop_motion(self, i: int) -> None:
        """The motion ended: the window empties and the rate reads 0.0."""
        self._ring[i] = False
        self._filled[i] = 0
        self._answered_sum[i] = 0
        self._answered[i] = False
        self.started[i] = False
        self.lost_run[i] = 0
        self.longest_lost_run[i] = 0
        self.lost_total[i] = 0
        self.motion_first_id[i] = np.iinfo(np.uint64).max

    def rearm(self, i: int) -> None:
        """AutomaticErrorRecovery re-arms the lost-cycle bound."""
        self.lost_run[i] = 0

    def mark_answered(self, fresh: np.ndarray) -> None:
        """A command echoing the open cycle's id arrived for these robots."""
        self._answered |= fresh

    def mark_first_command(self, applied: np.ndarray) -> None:
        self.started |= applied

    def close_cycle(self, counting: np.ndarray) -> None:
        """Close the open cycle for the robots whose accounting is open."""
        pos = self._pos
        answered = self._answered & counting
        old = self._ring[:, pos]
        # Robots not counting keep their (empty) window untouched.
        full = self._filled >= self.window
        self._answered_sum += np.where(counting, answered.astype(np.int64) - (old & full), 0)
        self._ring[:, pos] = np.where(counting, answered, old)
        self._filled = np.where(counting, np.minimum(self._filled + 1, self.window), self._filled)
        lost = counting & ~answered
        self.lost_run = np.where(lost, self.lost_run + 1, np.where(counting, 0, self.lost_run))
        self.lost_total += lost
        self.longest_lost_run = np.maximum(self.longest_lost_run, self.lost_run)
        self._answered[:] = False
        self._pos = (pos + 1) % self.window

    def success_rate(self) -> np.ndarray:
        """control_command_success_rate per robot: answered / cycles held by the window."""
        return np.where(self._filled > 0, self._answered_sum / np.maximum(self._filled, 1), 0.0)
