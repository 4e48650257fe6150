"""The Cartesian generators' history: one row per robot, its last real sample and its ring.

Everything the next Cartesian command is differenced against — the pose and its
derivatives, the twist, the elbow, the reported twist and the IK joint history —
lives side by side in one float64 row per robot (``CartesianHistory``), so that
the three operations docs/fci-behaviour.md "A datagram that turns up late replaces the guess
it stood in for" needs are one copy each:

* when a run of guesses begins, the last real sample is snapshotted (never on a
  cycle a command arrived in: the all-fresh path pays nothing for it);
* the datagram a run is missing restores that sample (the rewind);
* every published state's history is remembered in a ring of ``RING`` rows, so a
  replay, a duplicate or a reordered datagram is judged against the reference of
  the state it answers, as ``JointReference`` does for q_c / dq_c.
"""

from __future__ import annotations

import numpy as np

from ..reference import RING

#: columns of one robot's history (the layout of ``CartesianHistory``): T, the pose's
#: [v | omega] and [a | alpha], the frozen [a | alpha], twist, dtwist, the frozen dtwist,
#: the reported twist and its rate, elbow, de, dde, the frozen dde, the elbow flag,
#: q_ik, dq_ik, ddq_ik, ik_warm
WIDTH = 16 + 12 + 6 + 3 * 6 + 2 * 6 + 2 + 3 + 1 + 3 * 7 + 1


class _Columns:
    """Hands out consecutive column ranges of an (n, width) buffer as shaped views."""

    def __init__(self, buffer: np.ndarray) -> None:
        self.buffer = buffer
        self.used = 0

    def __call__(self, *shape: int) -> np.ndarray:
        size = int(np.prod(shape)) if shape else 1
        block = self.buffer[:, self.used : self.used + size]
        self.used += size
        view = block.reshape(len(self.buffer), *shape) if shape else block[:, 0]
        if not np.shares_memory(view, self.buffer):  # reshape must not copy
            raise AssertionError("a history field is not a view of the buffer")
        return view


class CartesianHistory:
    """Named views of one (n, ``WIDTH``) history buffer (the live one or a published one).

    ``has_elbow`` is the bool mirror of the ``elbow_flag`` column (masks need bools);
    change both through :meth:`set_has_elbow`.
    """

    def __init__(self, buffer: np.ndarray) -> None:
        self.buffer = buffer
        take = _Columns(buffer)
        #: the commanded (pose motion) or twist-integrated (twist motion) EE pose
        self.T = take(4, 4)
        #: the pose's history, (n, 2, 6): [[v | omega], [a | alpha]]
        self.history = take(2, 6)
        self.v, self.omega = self.history[:, 0, :3], self.history[:, 0, 3:]
        self.a, self.alpha = self.history[:, 1, :3], self.history[:, 1, 3:]
        #: the acceleration frozen for extrapolation, [a | alpha]
        self.acceleration_frozen = take(6)
        self.a_frozen = self.acceleration_frozen[:, :3]
        self.alpha_frozen = self.acceleration_frozen[:, 3:]
        #: the commanded twist, its acceleration and the frozen acceleration
        self.twist, self.dtwist, self.dtwist_frozen = take(6), take(6), take(6)
        #: the twist the state reports (O_dP_EE_d / O_dP_EE_c) and its rate (O_ddP_EE_c)
        self.reported, self.dreported = take(6), take(6)
        #: the commanded elbow while one is streamed, and elbow[0]'s derivatives
        self.elbow = take(2)
        self.de, self.dde, self.dde_frozen = take(), take(), take()
        #: 1.0 while an elbow is streamed (has_elbow), 0.0 otherwise
        self.elbow_flag = take()
        #: the IK solution history, (n, 3, 7): [q_ik, dq_ik, ddq_ik] (q_ik is the joint
        #: servo's reference)
        self.joint = take(3, 7)
        self.q_ik, self.dq_ik, self.ddq_ik = self.joint[:, 0], self.joint[:, 1], self.joint[:, 2]
        #: converged IK samples since the joint history was last rebased (a count)
        self.ik_warm = take()
        if take.used != WIDTH:
            raise AssertionError("the history layout and WIDTH disagree")
        self.has_elbow = self.elbow_flag > 0.0

    def column(self, view: np.ndarray) -> int:
        """The first column of the field ``view`` in a row of the buffer (the layout the
        C arithmetic reads: fci/cartesian/_history.c)."""
        start = view.__array_interface__["data"][0] - self.buffer.__array_interface__["data"][0]
        return start // self.buffer.itemsize

    def set_has_elbow(self, has_elbow: np.ndarray) -> None:
        """Set the (n,) elbow flags, the bool mirror and the buffer's column alike."""
        self.has_elbow[...] = has_elbow
        self.elbow_flag[...] = has_elbow


class CartesianReference(CartesianHistory):
    """The live Cartesian history of n robots, with what a late datagram is judged against.

    ``real_echo`` and ``run`` mean what they mean in ``JointReference``: the message
    id the last command that actually arrived echoed, and the cycles guessed since.
    """

    def __init__(self, n: int) -> None:
        super().__init__(np.zeros((n, WIDTH)))
        self.n = n
        #: the message id the last command that actually arrived echoed
        self.real_echo = np.zeros(n, dtype=np.uint64)
        #: cycles guessed (extrapolated or held) since that command
        self.run = np.zeros(n, dtype=np.int64)
        # The last real sample, snapshotted when a run of guesses begins.
        self._real = np.zeros_like(self.buffer)
        # The history as the last RING published states carried it, by message id;
        # (RING, n, WIDTH), so that remembering a state is one contiguous copy.
        self._ring = np.zeros((RING, n, WIDTH))
        self._robots = np.arange(n)

    def start(self, i: int, echo: int) -> None:
        """Robot i's motion starts at rest (the caller sets T, elbow and q_ik); ``echo``
        is the last published id, whose state now carries this history."""
        self.buffer[i] = 0.0
        self.has_elbow[i] = False
        self.real_echo[i] = echo
        self.run[i] = 0

    def remember_robot(self, i: int, message_id: int) -> None:
        """Robot i's history as published in state ``message_id`` (a motion's start)."""
        self._ring[message_id % RING, i] = self.buffer[i]

    def remember(self, message_id: int) -> None:
        """The history as published in state ``message_id`` (every cycle: one copy)."""
        self._ring[message_id % RING] = self.buffer

    def published(self, ids: np.ndarray, current: int) -> CartesianHistory:
        """The history as published in state ``ids[i]`` for each robot; the history as it
        stands for an id older than the ring (a replay). ``current``: the last published id."""
        ids = ids.astype(np.int64)
        recent = (current - ids < RING)[:, None]
        rows = np.where(recent, self._ring[ids % RING, self._robots], self.buffer)
        return CartesianHistory(rows)

    def begin_guesses(self, lost: np.ndarray) -> None:
        """``lost`` robots are guessed this cycle: where a run begins, remember the real
        sample the history stands at (docs/fci-behaviour.md: the guesses are what a late datagram
        throws away, and it is differenced against "the last command that actually arrived")."""
        starting = lost & (self.run == 0)
        if np.count_nonzero(starting):
            np.copyto(self._real, self.buffer, where=starting[:, None])
        self.run += lost

    def rewind(self, rows: np.ndarray) -> None:
        """Throw the guessed run of ``rows`` away: the history is the last real sample again.

        A robot with no guess since its last real sample is already there.
        """
        rows = rows & (self.run > 0)
        if not np.count_nonzero(rows):
            return
        np.copyto(self.buffer, self._real, where=rows[:, None])
        np.copyto(self.has_elbow, self.elbow_flag > 0.0, where=rows)
        self.run[rows] = 0
