"""The replies waiting for one client's TCP socket, sent by a thread of their own.

The robot's 1 kHz loop does not depend on a client's TCP window: the tick thread
(and the gripper's timer) only queue a reply here and return at once. A writer
thread per connection drains the queue. A client that does not read its replies
stalls only that writer; once a reply has waited longer than ``max_delay`` or the
queue holds more than ``max_bytes``, the connection is given up (``on_stuck``),
and the server goes on ticking. The bounds are stated in docs/socket.md.
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections import deque
from collections.abc import Callable

#: How long a reply may wait to be delivered before the client is dropped [s].
MAX_REPLY_DELAY_S = 1.0
#: How many reply bytes may wait (beyond the kernel's send buffer) before the client is dropped.
MAX_OUTBOX_BYTES = 8 * 1024 * 1024
#: The kernel's send buffer asked for each client socket: a fixed size keeps what a
#: client that does not read can hold up to the outbox bound plus this.
SEND_BUFFER_BYTES = 64 * 1024


class Outbox:
    """A bounded queue of replies for one socket, sent on the outbox's own thread.

    Args:
        sock: the connected socket (blocking; reads stay with its session).
        name: how the log names the client (e.g. ``"client 127.0.0.1:5000"``).
        log: where a dropped client is logged.
        on_stuck: called once, on the writer thread, when a bound is passed; it
            should end the connection (the session's reader then cleans up).
    """

    def __init__(
        self,
        sock: socket.socket,
        name: str,
        log: logging.Logger,
        on_stuck: Callable[[], None],
        max_delay: float = MAX_REPLY_DELAY_S,
        max_bytes: int = MAX_OUTBOX_BYTES,
    ) -> None:
        self._sock = sock
        self._name = name
        self._log = log
        self._on_stuck = on_stuck
        self.max_delay = max_delay
        self.max_bytes = max_bytes
        self._cond = threading.Condition()
        self._queue: deque[tuple[float, bytes]] = deque()
        self._bytes = 0
        self._closed = False
        self._overflow = False
        self.thread = threading.Thread(target=self._run, name=f"outbox-{name}", daemon=True)

    def put(self, data: bytes) -> None:
        """Queue ``data`` for sending; never blocks (past a bound, the client is dropped)."""
        with self._cond:
            if self._closed or self._overflow:
                return
            self._queue.append((time.monotonic(), data))
            self._bytes += len(data)
            if self._bytes > self.max_bytes:
                self._overflow = True
            self._cond.notify()

    def close(self) -> None:
        """Stop the writer (what is still queued is not sent)."""
        with self._cond:
            self._closed = True
            self._cond.notify()

    def _run(self) -> None:
        poller = select.poll()
        poller.register(self._sock, select.POLLOUT)
        while True:
            with self._cond:
                while not (self._queue or self._closed or self._overflow):
                    self._cond.wait()
                if self._closed:
                    return
                if self._overflow:
                    why = f"more than {self.max_bytes} bytes of replies waiting"
                    break
                since, data = self._queue[0]
            delivered = self._send(poller, data, since + self.max_delay)
            if delivered is None:  # the connection is gone: its reader notices
                return
            if not delivered:
                if self._overflow:
                    why = f"more than {self.max_bytes} bytes of replies waiting"
                else:
                    why = f"a reply undelivered for {self.max_delay:g} s"
                break
            with self._cond:
                self._queue.popleft()
                self._bytes -= len(data)
        self._log.warning(
            "%s does not read its replies (%s): disconnected; the robot goes on", self._name, why
        )
        self._on_stuck()

    def _send(self, poller: select.poll, data: bytes, deadline: float) -> bool | None:
        """True when all of ``data`` went out, False past ``deadline``, None on a closed socket."""
        view = memoryview(data)
        while view:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            if self._closed:
                return None
            if self._overflow:
                return False
            # Wake at least every 0.1 s to notice close().
            if not poller.poll(min(remaining, 0.1) * 1000.0):
                continue
            try:
                sent = self._sock.send(view, socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError:
                return None
            view = view[sent:]
        return True
