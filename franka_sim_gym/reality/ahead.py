"""Per-robot random streams drawn ahead in blocks: a cycle costs one view for every robot,
whatever n is, and robot i's values are its own stream's in order, whenever its episode
began (so arm i of a batch sees what a single env of the same seed sees).

Robot i's k-th sample since its stream (re)started at cycle t0 sits in a ring at
(t0 + k) mod BLOCK: every robot's sample of a cycle is one column of the ring. Samples
move on only at :meth:`Ahead.advance` (once per cycle): reading again between cycles
gives the same values.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Samples drawn ahead per robot.
BLOCK = 256


class Ahead:
    """n robots' streams of ``width`` values per sample.

    Args:
        n: robots.
        width: values per sample.
        sample: ``sample(rng, robot, count)`` -> (count, width): the next ``count``
            samples of ``robot`` from its generator ``rng`` (scaled as the caller wants).
    """

    def __init__(
        self, n: int, width: int, sample: Callable[[np.random.Generator, int, int], np.ndarray]
    ) -> None:
        # (BLOCK, n, width): a cycle's samples are one contiguous row
        self._ring = np.zeros((BLOCK, n, width))
        self._rows = list(self._ring)  # its rows as views, made once (a cycle reads one)
        self._sample = sample
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._refill = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
        self._cycle = 0
        self._next = int(self._refill.min())  # the next cycle a robot's samples run out

    def reseed(self, robots, rngs) -> None:
        """``robots`` start over from the generators ``rngs`` (one each) this cycle."""
        for k, i in enumerate(np.atleast_1d(robots).tolist()):
            self._rngs[i] = rngs[k]
            self._fill(i)
        self._next = int(self._refill.min())

    def _fill(self, i: int) -> None:
        """Robot i's next BLOCK samples, the first at this cycle."""
        block = self._sample(self._rngs[i], i, BLOCK)
        at = self._cycle % BLOCK  # sample k goes to slot (cycle + k) mod BLOCK
        self._ring[at:, i] = block[: BLOCK - at]
        self._ring[:at, i] = block[BLOCK - at :]
        self._refill[i] = self._cycle + BLOCK

    def advance(self) -> None:
        """Every robot on to its next sample (one cycle)."""
        self._cycle += 1
        if self._cycle == self._next:
            for i in np.flatnonzero(self._refill == self._cycle).tolist():
                self._fill(i)
            self._next = int(self._refill.min())

    def take(self, count: int) -> np.ndarray:
        """(count, n, width): every robot's samples of this cycle and the ``count - 1``
        next, a copy; afterwards the stream is ``count`` cycles on (as many advances)."""
        # In spans up to each refill (a robot running out) or the ring's wrap: one span
        # when neither falls within them, the common case.
        out = np.empty((count, *self._ring.shape[1:]))
        k = 0
        while k < count:
            at = self._cycle % BLOCK
            span = max(1, min(count - k, self._next - self._cycle, BLOCK - at))
            out[k : k + span] = self._ring[at : at + span]
            k += span
            self._cycle += span - 1
            self.advance()  # the refills due at the span's last cycle, if any
        return out

    def current(self) -> np.ndarray:
        """(n, width) every robot's sample of this cycle (a view, valid until the next
        :meth:`advance`)."""
        return self._rows[self._cycle % BLOCK]

    def next(self) -> np.ndarray:
        """:meth:`advance`, then :meth:`current` (a cycle's one call)."""
        self.advance()
        return self._rows[self._cycle % BLOCK]
