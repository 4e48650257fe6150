"""Warnings that can repeat every cycle, rate-limited in cycles.

A client can make a warning due on every 1 ms cycle (stray datagrams with ids
no state carried, non-finite commands); one line each would flood the log and
cost the cycle its formatting. The first occurrence of each kind is logged at
once; later ones are counted, and the first one at least ``interval`` cycles
after the last line is logged with the count of those in between. Time is the
robot's cycle count, as everywhere in this package (it reads no clock):
1000 cycles are 1 s.
"""

from __future__ import annotations

import logging
from collections.abc import Hashable

#: Cycles between two lines of one kind: 1 s at the robot's 1 kHz.
INTERVAL_CYCLES = 1000


class CycleLogLimit:
    """Logs each kind of warning at most once per ``interval`` cycles, counting the rest."""

    def __init__(self, logger: logging.Logger, interval: int = INTERVAL_CYCLES) -> None:
        self._log = logger
        self.interval = interval
        self._last: dict[Hashable, int] = {}
        self._suppressed: dict[Hashable, int] = {}

    def warning(self, cycle: int, kind: Hashable, message: str, *args: object) -> bool:
        """Log ``message % args`` as a warning unless ``kind`` was logged in the last
        ``interval`` cycles before ``cycle`` (then it is only counted). True if logged."""
        last = self._last.get(kind)
        if last is not None and 0 <= cycle - last < self.interval:
            self._suppressed[kind] = self._suppressed.get(kind, 0) + 1
            return False
        suppressed = self._suppressed.pop(kind, 0)
        self._last[kind] = cycle
        if suppressed:
            message += " (and %d more like it in the %d cycles before)"
            args = (*args, suppressed, cycle - last)
        self._log.warning(message, *args)
        return True
