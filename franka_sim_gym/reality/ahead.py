"""Per-robot random streams drawn ahead in blocks: a cycle costs one lookup for every
robot, whatever n is, and robot i's values are its own stream's, whenever its episode
began (so arm i of a batch sees what a single env of the same seed sees).

A robot's sample moves on only at :meth:`Ahead.advance` (once per cycle): reading it
again between cycles gives the same values.
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
        self._block = np.zeros((n, BLOCK, width))
        self._sample = sample
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._pos = np.zeros(n, dtype=np.intp)
        self._rows = np.arange(n)
        self._left = BLOCK  # cycles until some robot's block runs out

    def reseed(self, robots, rngs) -> None:
        """``robots`` start over from the generators ``rngs`` (one each)."""
        for k, i in enumerate(np.atleast_1d(robots).tolist()):
            self._rngs[i] = rngs[k]
            self._fill(i)
        self._left = BLOCK - int(self._pos.max())

    def _fill(self, i: int) -> None:
        rng = self._rngs[i]
        if rng is not None:
            self._block[i] = self._sample(rng, i, BLOCK)
        self._pos[i] = 0

    def advance(self) -> None:
        """Every robot on to its next sample (one cycle)."""
        self._pos += 1
        self._left -= 1
        if self._left == 0:
            for i in np.flatnonzero(self._pos >= BLOCK).tolist():
                self._fill(i)
            self._left = BLOCK - int(self._pos.max())

    def current(self) -> np.ndarray:
        """(n, width) every robot's sample of this cycle (a new array)."""
        return self._block[self._rows, self._pos]
