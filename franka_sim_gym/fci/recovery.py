"""AutomaticErrorRecovery's deferred reply: waiting for the arm to stand still.

docs/fci-behaviour.md "Enabling the violation": the reply comes once the measured |dq| < 0.005 rad/s
for 50 consecutive cycles, or after 0.7 s at the latest (the thresholds are
``ControllerConfig.recovery_*``).
"""

from __future__ import annotations

import logging

import numpy as np

from .config import ControllerConfig

log = logging.getLogger("franka_sim_gym.fci")


class RecoveryWait:
    """The robots waiting for standstill after AutomaticErrorRecovery."""

    def __init__(self, n: int, config: ControllerConfig) -> None:
        self.config = config
        #: cycles waited, -1 = not waiting
        self.waited = np.full(n, -1, dtype=np.int64)
        #: consecutive cycles at standstill
        self.settled = np.zeros(n, dtype=np.int64)
        #: how many robots wait (a Python int: the cycle skips the check when 0)
        self.count = 0

    def begin(self, i: int) -> None:
        """Robot i starts waiting."""
        self.waited[i] = 0
        self.settled[i] = 0
        self._recount()

    def end(self, i: int) -> None:
        """Robot i no longer waits (answered, reset or disconnected)."""
        self.waited[i] = -1
        self.settled[i] = 0
        self._recount()

    def waiting(self, i: int) -> bool:
        return bool(self.waited[i] >= 0)

    def advance(self, dq: np.ndarray) -> list[int]:
        """One cycle with measured joint velocities ``dq``: the robots whose wait is over."""
        cfg = self.config
        waiting = self.waited >= 0
        still = np.all(np.abs(dq) < cfg.recovery_velocity_threshold, axis=1)
        self.settled = np.where(waiting & still, self.settled + 1, 0)
        self.waited[waiting] += 1
        done = waiting & (
            (self.settled >= cfg.recovery_settle_cycles) | (self.waited >= cfg.recovery_max_cycles)
        )
        robots = np.flatnonzero(done).tolist()
        for i in robots:
            if self.settled[i] < cfg.recovery_settle_cycles:
                log.warning("robot %d: recovery answered at the 0.7 s cap before standstill", i)
            else:
                log.info("robot %d: recovery answered after %d cycles", i, self.waited[i])
        return robots

    def _recount(self) -> None:
        self.count = int(np.count_nonzero(self.waited >= 0))
