"""Late datagrams' joint intents: what drives the servo for the cycle one arrived in.

docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood in
for": a late datagram drives the servo for the cycle it arrived in (nothing fresher
arrived), but it is never recorded as a sample of the commanded trajectory. The
joint and Cartesian generators hand its joint intent here (q_c itself, one cycle of
dq_c, or the IK solution of a late pose or twist); the controller asks for the
servo's target every cycle, so an intent never outlives the cycle it arrived in.
"""

from __future__ import annotations

import numpy as np


class LateIntents:
    """The joint intents of late datagrams of n robots, for the open cycle."""

    def __init__(self, n: int) -> None:
        self.rows = np.zeros(n, dtype=bool)
        #: some robot has an intent (the servo's usual answer, no, without a reduce)
        self.pending = False
        self.q = np.zeros((n, 7))
        self.dq = np.zeros((n, 7))

    def apply(self, rows: np.ndarray, q, dq) -> None:
        """``rows`` received a late datagram whose joint intent is (``q``, ``dq``); the
        history the next command is judged against is untouched."""
        r = rows[:, None]
        np.copyto(self.q, q, where=r)
        np.copyto(self.dq, dq, where=r)
        self.rows |= rows
        self.pending = True

    def servo(
        self, q_ref: np.ndarray, dq_ref: np.ndarray | None, have: np.ndarray, moving: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The servo's target this cycle: the late intents of robots still ``moving`` for
        which no fresh command arrived (``have``), the given target elsewhere; forgets
        the intents."""
        if not self.pending:
            return q_ref, dq_ref
        rows = (self.rows & ~have & moving)[:, None]
        self.rows[...] = False
        self.pending = False
        dq = np.zeros_like(q_ref) if dq_ref is None else dq_ref
        return np.where(rows, self.q, q_ref), np.where(rows, self.dq, dq)
