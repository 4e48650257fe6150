"""What the robot's joint sensors report: the true q, dq and tau_J with noise, and a
torque offset per episode (docs/reality.md, "Sensors").

Each robot's noise is its own stream (seeded per episode: reality/draw.py ``streams``),
drawn ahead (reality/ahead.py). A robot's sample moves on once per cycle: a state
published again between cycles (a reset of another robot) reads the same sample, so it
reports what it reported.
"""

from __future__ import annotations

import numpy as np

from ...reality.ahead import Ahead

#: The layout of a sample: q (7), dq (7), tau_J (7).
Q, DQ, TAU = slice(0, 7), slice(7, 14), slice(14, 21)


class SensorNoise(Ahead):
    """The noise of n robots' joint sensors, sample by sample (q, dq, tau_J).

    Args:
        n: robots.
    """

    def __init__(self, n: int) -> None:
        self._scale = np.zeros((n, 21))
        self._offset = np.zeros((n, 21))
        super().__init__(n, 21, self._noise)

    def _noise(self, rng: np.random.Generator, i: int, count: int) -> np.ndarray:
        return rng.standard_normal((count, 21)) * self._scale[i] + self._offset[i]

    def set(self, robots, rngs, q_noise, dq_noise, tau_noise, tau_offset) -> None:
        """A new episode for ``robots``: their streams ``rngs``, standard deviations and
        torque offsets (rows, (k, 7) each)."""
        for k, i in enumerate(np.atleast_1d(robots).tolist()):
            self._scale[i] = np.concatenate([q_noise[k], dq_noise[k], tau_noise[k]])
            self._offset[i, TAU] = tau_offset[k]
        self.reseed(robots, rngs)
