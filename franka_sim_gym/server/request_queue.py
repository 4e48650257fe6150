"""Requests handed from a TCP thread to the thread that owns the simulation.

Both servers keep MuJoCo and the controller on one thread (the robot's 1 kHz
tick, the hand's timer); a session thread queues a closure and that thread
applies it between steps. A failing request is logged and never kills the
owning thread.
"""

from __future__ import annotations

import logging
import queue
from collections.abc import Callable


def apply_pending(
    requests: queue.SimpleQueue[Callable[[], None]], log: logging.Logger, what: str
) -> None:
    """Apply every queued request now, in order; log the ones that raise."""
    # Called every 1 ms tick and nearly always empty: a C call instead of raising Empty.
    while not requests.empty():
        try:
            apply = requests.get_nowait()
        except queue.Empty:
            return
        try:
            apply()
        except Exception:  # a request must never kill the owning thread
            log.exception("%s failed", what)
