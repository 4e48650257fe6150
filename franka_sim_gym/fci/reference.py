"""The commanded joint signal and its backward-Euler history (q_d, dq_d, ddq_d).

One module owns the differencing history that the motion-limit checks and
the lost-cycle extrapolation both read (docs/fci-behaviour.md "The difference formulas"
and "What the sim does with a lost cycle"), so there is one copy of it.

The arrays are the published q_d / dq_d / ddq_d themselves (views into the
state's float64 shadow), updated in place: what the robot applied is exactly
what it reports, and the next command is differenced against that. A cycle's
record (a real command, a lost cycle's guess, a hold at rest) is written by the joint
generators' C cycle (fci/limits/_joint.c ``JointCycle``, ``joint_record``); this
module seeds, rewinds and remembers.
"""

from __future__ import annotations

import numpy as np

from .tables import DELTA_T

#: published references kept for judging late datagrams: more than the 20 cycles
#: after which a motion stops being extrapolated (a later datagram is a replay)
RING = 32

_RATE = 1.0 / DELTA_T


class JointReference:
    """Per robot: the joint reference published as q_d / dq_d / ddq_d.

    ``ddq_frozen`` is the acceleration the last two commands that actually
    arrived implied, which a lost cycle continues with (frozen, not re-derived
    from extrapolated samples: docs/fci-behaviour.md "Frozen, not continued").
    """

    def __init__(self, columns: tuple[np.ndarray, tuple[int, int, int]]) -> None:
        # The published state's columns holding q_d, dq_d and ddq_d
        # (StateWriter.reference_columns) and where each starts in them: q, dq and ddq are
        # their views, and the ring copies them at once.
        self._columns, self._starts = columns
        self.q, self.dq, self.ddq = (self._columns[:, k : k + 7] for k in self._starts)
        q = self.q
        self.ddq_frozen = np.zeros_like(q)
        n = q.shape[0]
        #: the message id the last command that actually arrived echoed
        self.real_echo = np.zeros(n, dtype=np.uint64)
        #: extrapolated samples recorded since that command (the current run)
        self.run = np.zeros(n, dtype=np.int64)
        # The last real sample, snapshotted when an extrapolated run begins, so a
        # late datagram can throw the run's guesses away (docs/fci-behaviour.md "A datagram that
        # turns up late replaces the guess it stood in for").
        self._real_q = np.zeros_like(q)
        self._real_dq = np.zeros_like(q)
        self._real_ddq = np.zeros_like(q)
        # The references the last RING published states carried (by message id), so
        # a late datagram is judged against the reference of the state it answers.
        self._ring = np.zeros((n, RING, self._columns.shape[1]))
        #: the arrays the joint generators' cycle records into, in its order (fci/limits/
        #: _joint.c JointCycle / joint_record: the record's only text)
        self.arrays = (
            self.q, self.dq, self.ddq, self.ddq_frozen,
            self._real_q, self._real_dq, self._real_ddq, self.real_echo, self.run,
        )  # fmt: skip

    def remember(self, message_id: int) -> None:
        """Store the reference as published in state ``message_id``."""
        self._ring[:, message_id % RING] = self._columns

    def published(self, ids: np.ndarray, current: int) -> tuple[np.ndarray, ...] | None:
        """(q, dq, ddq) as published in state ``ids[i]`` for each robot, (n, 7) each;
        None when some id is older than the ring (the caller uses the reference as it
        stands). ``current`` is the last published id."""
        ids = ids.astype(np.int64)
        if np.any(current - ids >= RING):
            return None
        rows = np.arange(ids.shape[0])
        k = ids % RING
        published = self._ring[rows, k]
        return tuple(published[:, start : start + 7] for start in self._starts)

    def seed(self, i: int, q: np.ndarray, echo: int) -> None:
        """Start robot i's motion at rest at ``q`` (a new Move); ``echo``: the last published id."""
        self.q[i] = q
        self.dq[i] = 0.0
        self.ddq[i] = 0.0
        self.ddq_frozen[i] = 0.0
        self.real_echo[i] = echo
        self.run[i] = 0

    def rewind(self, rows: np.ndarray) -> None:
        """Throw away the extrapolated run of ``rows``: the history is the last real sample.

        A robot with no guesses since its last real sample is already there.
        """
        rows = rows & (self.run > 0)
        r = rows[:, None]
        np.copyto(self.q, self._real_q, where=r)
        np.copyto(self.dq, self._real_dq, where=r)
        np.copyto(self.ddq, self._real_ddq, where=r)
        self.run[rows] = 0
