"""Rate-limited logging: a bad datagram stream at 1 kHz must not flood the log."""

from __future__ import annotations

import logging
import time


class RateLimitedLog:
    """Logs the first occurrence of each reason at once, then at most one summary per interval."""

    def __init__(self, logger: logging.Logger, interval: float = 1.0) -> None:
        self._log = logger
        self._interval = interval
        self._last: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def warning(self, reason: str, message: str, *args) -> None:
        """Log ``message`` under the named ``reason`` unless that reason logged recently."""
        now = time.monotonic()
        last = self._last.get(reason)
        if last is not None and now - last < self._interval:
            self._suppressed[reason] = self._suppressed.get(reason, 0) + 1
            return
        suppressed = self._suppressed.pop(reason, 0)
        self._last[reason] = now
        if suppressed:
            message += f" ({suppressed} more like it suppressed)"
        self._log.warning("%s: " + message, reason, *args)
