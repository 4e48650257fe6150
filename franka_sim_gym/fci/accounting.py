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

from .tables import SUCCESS_RATE_WINDOW

_NO_MOTION = np.iinfo(np.uint64).max


class CycleAccounting:
    """Per-robot success-rate window and lost-cycle run."""

    def __init__(self, n: int, window: int = SUCCESS_RATE_WINDOW) -> None:
        self.n = n
        self.window = window
        self._ring = np.zeros((n, window), dtype=bool)
        self._pos = 0  # one ring position for all robots; each robot's ring is cleared per motion
        self._counted = np.zeros(n, dtype=np.int64)
        self._held = np.zeros(n, dtype=np.int64)
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
        #: consecutive cycles every robot counted and answered (see close_cycle)
        self._steady = 0

    def start_motion(self, i: int, last_published_id: int) -> None:
        """A Move started; commands echoing states from now on belong to it."""
        self.stop_motion(i)
        self.motion_first_id[i] = last_published_id

    def stop_motion(self, i: int) -> None:
        """The motion ended: the window empties and the rate reads 0.0."""
        self._ring[i] = False
        self._counted[i] = 0
        self._held[i] = 0
        self._answered_sum[i] = 0
        self.answered[i] = False
        self.started[i] = False
        self.lost_run[i] = 0
        self.longest_lost_run[i] = 0
        self.lost_total[i] = 0
        self.motion_first_id[i] = _NO_MOTION
        self._rate[i] = 0.0
        self._steady = 0

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

    def close_cycle(self, n_started: int) -> None:
        """Close the open cycle for the robots whose accounting is open (``n_started`` of them)."""
        if self.n == 1:
            self._close_cycle_one(n_started)
            return
        answered = self.answered
        every = n_started == self.n and np.count_nonzero(answered) == self.n
        self._steady = self._steady + 1 if every else 0
        if self._steady > self.window:
            # every robot counted and answered for the whole window: every ring is full
            # of answers, the sums are the window, the rates 1.0 and the runs 0 already;
            # only the count goes on
            self._counted += 1
            answered[...] = False
            self._pos = (self._pos + 1) % self.window
            return
        column = self._ring[:, self._pos]  # the oldest entry, about to be replaced
        if every:
            # every robot counts and answered: nothing lost, no run goes on (the longest
            # stays the longest)
            self._answered_sum += 1
            self._answered_sum -= column
            column[...] = True
            self._counted += 1
            self.lost_run[...] = 0
        elif n_started == self.n:  # every robot counts: no masks
            self._answered_sum += answered
            self._answered_sum -= column
            column[...] = answered
            self._counted += 1
            lost = ~answered
            self.lost_total += lost
            self.lost_run += 1
            self.lost_run *= lost
            np.maximum(self.longest_lost_run, self.lost_run, out=self.longest_lost_run)
        else:
            counting = self.started
            lost = counting & ~answered
            entry = answered & counting  # robots not counting keep an empty (cleared) window
            self._answered_sum += entry
            self._answered_sum -= column
            column[...] = entry
            self._counted += counting
            self.lost_total += lost
            self.lost_run = np.where(lost, self.lost_run + 1, np.where(counting, 0, self.lost_run))
            np.maximum(self.longest_lost_run, self.lost_run, out=self.longest_lost_run)
        answered[...] = False
        self._pos = (self._pos + 1) % self.window
        # While the window fills the divisor is what it holds (never 0 here: an
        # empty window has an empty sum, and 0 / 1 reads 0.0 as between motions).
        np.minimum(self._counted, self.window, out=self._held)
        np.maximum(self._held, 1, out=self._held)
        np.divide(self._answered_sum, self._held, out=self._rate)

    def _close_cycle_one(self, n_started: int) -> None:
        """One robot: the same bookkeeping on Python scalars (a dozen numpy calls on
        size-1 arrays cost ~10 us a cycle; item reads and writes cost ~1.5 us)."""
        answered = bool(self.answered[0])
        self.answered[0] = False
        pos = self._pos
        self._pos = (pos + 1) % self.window
        if not n_started:
            return  # a robot not counting keeps its cleared window
        ring = self._ring
        old = bool(ring[0, pos])
        ring[0, pos] = answered
        total = int(self._answered_sum[0]) + answered - old
        self._answered_sum[0] = total
        counted = int(self._counted[0]) + 1
        self._counted[0] = counted
        if answered:
            self.lost_run[0] = 0
        else:
            run = int(self.lost_run[0]) + 1
            self.lost_run[0] = run
            self.lost_total[0] += 1
            if run > self.longest_lost_run[0]:
                self.longest_lost_run[0] = run
        held = counted if counted < self.window else self.window
        self._held[0] = held
        self._rate[0] = total / held

    def success_rate(self) -> np.ndarray:
        """control_command_success_rate per robot: answered / cycles held by the window."""
        return self._rate
