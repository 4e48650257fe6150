"""`serve --lockstep`: during a motion, the next cycle runs as soon as the client answered.

libfranka's control loop waits for each state, answers it, and takes its time from
``RobotState::time`` (docs/libfranka-client.md §5, §6), so nothing in the protocol
needs the robot's cycle to be 1 ms of wall time. In lockstep, while a motion runs,
the tick thread waits after each state for the command that answers it and runs the
next cycle at once; a command that has not come within ``timeout`` of wall time
leaves the cycle unanswered, counted as lost exactly as on the 1 kHz clock
(docs/fci-behaviour.md "The cycle contract"), so a client that hangs still meets the
communication-constraints reflex 20 cycles later. Outside a motion (Idle, Reflex,
recovery) the server keeps its 1 kHz wall-clock stream (server/pacing.py).

The wait happens on the tick thread, between two cycles: TCP requests that arrive
meanwhile (StopMove, a disconnect) are applied there at once (requests are applied
between cycles in both modes), and the wait ends when the motion did.
"""

from __future__ import annotations

import os
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

#: How long a state of a running motion waits for its answer by default [s].
DEFAULT_TIMEOUT_S = 0.05

#: The wall time a client has to answer a state on the robot's own clock [s]: an
#: answer slower than this would have missed its cycle without --lockstep.
REAL_TIME_BUDGET_S = 0.001


@dataclass
class AnswerTimes:
    """How fast the client answered the states of one motion, in wall time."""

    answered: int = 0
    over_budget: int = 0
    slowest_s: float = 0.0

    def add(self, seconds: float) -> None:
        self.answered += 1
        if seconds > REAL_TIME_BUDGET_S:
            self.over_budget += 1
        if seconds > self.slowest_s:
            self.slowest_s = seconds

    def summary(self) -> str:
        """One log line's worth: what lockstep hid from the robot's clock."""
        return (
            f"lockstep: {self.answered} answers, the slowest after {self.slowest_s * 1e3:.2f} ms; "
            f"{self.over_budget} took longer than the 1 ms a cycle lasts on the robot"
        )


class AnswerWait:
    """The tick thread's wait for the command answering the last published state.

    Args:
        udp_fd: the server's UDP socket (commands arrive there).
        timeout: how long a state waits for its answer [s].
    """

    def __init__(self, udp_fd: int, timeout: float = DEFAULT_TIMEOUT_S) -> None:
        if not timeout > 0:
            raise ValueError(f"the lockstep timeout must be > 0 s, got {timeout!r}")
        self.timeout = timeout
        self._wake_read, self._wake_write = os.pipe()
        # notify() runs on TCP threads, possibly while the server shuts down: it must
        # never write to a descriptor number that close() released (and the OS reused).
        self._wake_lock = threading.Lock()
        self._closed = False
        os.set_blocking(self._wake_read, False)
        os.set_blocking(self._wake_write, False)
        self._poller = select.poll()
        self._udp_fd = udp_fd
        self._poller.register(udp_fd, select.POLLIN)
        self._poller.register(self._wake_read, select.POLLIN)
        #: the running motion's answer times (reset by :meth:`take_times`)
        self.times = AnswerTimes()

    def notify(self) -> None:
        """A request was queued for the tick thread (any thread): end a poll at once."""
        with self._wake_lock:
            if self._closed:
                return
            try:
                os.write(self._wake_write, b"\0")
            except OSError:  # BlockingIOError included: full, so a wake-up is pending anyway
                pass

    def wait(
        self,
        waiting: Callable[[], bool],
        answered: Callable[[], bool],
        receive: Callable[[], None],
        apply_requests: Callable[[], None],
    ) -> bool:
        """Wait until the open cycle is answered (True) or ``timeout`` passed (False).

        ``waiting()`` says whether a motion still runs (a request may end it);
        ``receive()`` hands the datagrams that arrived to the controller, after which
        ``answered()`` says whether one answered the last state; ``apply_requests()``
        applies the TCP requests queued since the cycle.
        """
        start = time.perf_counter()
        deadline = start + self.timeout
        while True:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                return False
            for fd, _ in self._poller.poll(remaining * 1000.0):  # [ms], rounded up
                if fd == self._udp_fd:
                    receive()
                    if answered():
                        self.times.add(time.perf_counter() - start)
                        return True
                else:
                    self._drain()
                    apply_requests()
                    if not waiting():
                        return False

    def take_times(self) -> AnswerTimes:
        """The answer times gathered since the last call (one motion's)."""
        times, self.times = self.times, AnswerTimes()
        return times

    def close(self) -> None:
        """Release the wake-up pipe (after the tick thread has stopped)."""
        with self._wake_lock:
            if self._closed:
                return
            self._closed = True
            for fd in (self._wake_read, self._wake_write):
                os.close(fd)

    def _drain(self) -> None:
        try:
            while os.read(self._wake_read, 4096):
                pass
        except (BlockingIOError, OSError):
            pass
