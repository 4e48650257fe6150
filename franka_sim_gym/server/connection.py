"""One accepted TCP connection (the arm's or the hand's): its reader, its outbox, its deadline.

The reader thread decodes frames and hands each to the session; replies leave
through an :class:`~franka_sim_gym.server.outbox.Outbox`, so whoever answers
(the session, the tick thread, the gripper's timer) never waits on the client.
A connection that has not completed a valid Connect within ``connect_timeout``
is closed and logged: until then it holds nothing (the client slot belongs to
a client that connected, see :mod:`franka_sim_gym.server.client_slot`).
"""

from __future__ import annotations

import logging
import select
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterable

from .outbox import MAX_OUTBOX_BYTES, Outbox

#: How long a new connection may take to send a valid Connect [s].
CONNECT_TIMEOUT_S = 2.0
#: What may wait in the outbox of a connection that has not connected: its only
#: replies are rejections, a few bytes each.
UNCONNECTED_OUTBOX_BYTES = 64 * 1024
#: SO_LINGER on, 0 s: close() resets the connection (see Connection.close).
_RESET_ON_CLOSE = struct.pack("ii", 1, 0)


class Connection:
    """The transport of one session.

    Args:
        sock: the accepted socket.
        peer: its (address, port).
        name: how the log names it (``"client 127.0.0.1:40000"``).
        log: the server's logger.
        feed: the session's frame decoder (bytes in, frames or framing errors out).
        handle: called on the reader thread with each decoded item.
        on_end: called once on the reader thread when the connection is over.
        connect_timeout: the bound on the first valid Connect [s].
    """

    def __init__(
        self,
        sock: socket.socket,
        peer: tuple[str, int],
        name: str,
        log: logging.Logger,
        feed: Callable[[bytes], Iterable],
        handle: Callable[[object], None],
        on_end: Callable[[], None],
        connect_timeout: float = CONNECT_TIMEOUT_S,
    ) -> None:
        self.sock = sock
        self.peer = peer
        self.name = name
        self.log = log
        self.connected = False
        self.closed = threading.Event()
        self._feed = feed
        self._handle = handle
        self._on_end = on_end
        self._deadline = time.monotonic() + connect_timeout
        self._connect_timeout = connect_timeout
        self.outbox = Outbox(sock, name, log, self.close, max_bytes=UNCONNECTED_OUTBOX_BYTES)
        self.thread = threading.Thread(target=self._run, name=f"reader-{name}", daemon=True)

    def start(self) -> None:
        self.outbox.thread.start()
        self.thread.start()

    def send(self, data: bytes) -> None:
        """Queue a reply (never blocks; see :class:`Outbox`)."""
        self.outbox.put(data)

    def mark_connected(self) -> None:
        """A valid Connect was answered: no deadline any more, the full outbox bound."""
        self.connected = True
        self.outbox.max_bytes = MAX_OUTBOX_BYTES

    def close(self) -> None:
        """End the connection from any thread: the reader wakes and closes it with a reset.

        A reset, not a FIN: libfranka polls its TCP socket only for errors and for
        data (src/network.h, tcpReadFromBuffer), so after a plain end of stream a
        client waiting for a reply would wait for ever; a reset makes it raise
        NetworkException ("TCP connection got interrupted") at once.
        """
        try:
            self.sock.shutdown(socket.SHUT_RD)  # wakes the reader; sends nothing
        except OSError:
            pass

    def _run(self) -> None:
        poller = select.poll()
        poller.register(self.sock, select.POLLIN)
        try:
            while True:
                if not self.connected:
                    remaining = self._deadline - time.monotonic()
                    if remaining <= 0 or not poller.poll(remaining * 1000.0):
                        self.log.warning(
                            "%s sent no valid Connect within %g s: connection closed",
                            self.name,
                            self._connect_timeout,
                        )
                        break
                try:
                    data = self.sock.recv(65536)
                except OSError as exc:
                    self.log.info("%s: connection error (%s)", self.name, exc)
                    break
                if not data:
                    break
                for item in self._feed(data):
                    self._handle(item)
        finally:
            self.closed.set()
            self.outbox.close()
            self.close()
            self.outbox.thread.join(timeout=2.0)
            try:
                self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _RESET_ON_CLOSE)
                self.sock.close()
            except OSError:
                pass
            self._on_end()
