"""One client at a time on a listening TCP socket (the arm's port and the hand's alike).

Every connection is accepted; the slot belongs to the one that completes a valid
Connect (:meth:`ClientSlot.claim`). So connections that never send one (a port
scanner, a half-written header) hold nothing and are closed after the connect
timeout (:mod:`franka_sim_gym.server.connection`), and a client that reconnects
right after closing its previous connection is never refused: if the holder's
peer has already closed, the claim waits for the server to notice. A second
client while a live one holds the slot is refused with a clear log line and its
connection closed, while the first keeps running.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Protocol

from .logging_util import RateLimitedLog
from .outbox import SEND_BUFFER_BYTES

log = logging.getLogger("franka_sim_gym.server")

#: Connections without a Connect kept at once; a new one beyond closes the oldest,
#: so idle connections can never keep a real client out.
MAX_UNCONNECTED = 16
#: How long a Connect waits for a live holder to go before it is refused [s].
HOLDER_GRACE_S = 0.2
#: How long a Connect waits for a holder whose peer has already closed [s]
#: (the server notices within milliseconds; the bound covers a starved host).
CLOSING_HOLDER_WAIT_S = 5.0
_ESTABLISHED = 1  # Linux's TCP_ESTABLISHED (include/net/tcp_states.h)


class Session(Protocol):
    """What the slot needs of a session."""

    @property
    def sock(self) -> socket.socket: ...

    @property
    def peer(self) -> tuple[str, int]: ...

    def start(self) -> None: ...

    def close(self) -> None: ...


def peer_has_closed(sock: socket.socket) -> bool:
    """Whether the other end of ``sock`` has closed (or reset) the connection.

    TCP_INFO's state says so even when unread requests precede the FIN; where it
    is not available, a peek that reads end-of-stream does.
    """
    try:
        return sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 8)[0] != _ESTABLISHED
    except (AttributeError, OSError):
        pass
    try:
        return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except (BlockingIOError, InterruptedError):
        return False
    except OSError:
        return True


class ClientSlot:
    """Holds the one connected session of a server.

    Args:
        kind: how the log names the client ("" for the arm, "gripper " for the hand).
        make_session: builds the session for an accepted (socket, peer).
    """

    def __init__(self, kind: str, make_session: Callable[[socket.socket, tuple], Session]):
        self.kind = kind
        self.make_session = make_session
        self._cond = threading.Condition()
        self._unconnected: deque[Session] = deque()
        self._log = RateLimitedLog(log)  # a connection flood must not flood the log
        self.session: Session | None = None

    def accept_loop(self, tcp: socket.socket, running: threading.Event) -> None:
        """Accept until ``running`` clears (``tcp`` has a timeout so the flag is polled)."""
        while running.is_set():
            try:
                sock, peer = tcp.accept()
            except TimeoutError:
                continue
            except OSError:
                break
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
            session = self.make_session(sock, peer)
            with self._cond:
                self._unconnected.append(session)
                oldest = (
                    self._unconnected.popleft()
                    if len(self._unconnected) > MAX_UNCONNECTED
                    else None
                )
            if oldest is not None:
                self._log.warning(
                    "too-many-unconnected",
                    "closing the %sconnection from %s:%d: more than %d connections have "
                    "not sent a Connect",
                    self.kind,
                    oldest.peer[0],
                    oldest.peer[1],
                    MAX_UNCONNECTED,
                )
                oldest.close()
            session.start()

    def claim(self, session: Session) -> bool:
        """``session`` completed a valid Connect: give it the slot, or refuse (False, logged).

        A holder whose peer has closed is waited for (up to ``CLOSING_HOLDER_WAIT_S``);
        a live holder for ``HOLDER_GRACE_S`` only.
        """
        start = time.monotonic()
        with self._cond:
            if session in self._unconnected:
                self._unconnected.remove(session)
            while True:
                holder = self.session
                if holder is None or holder is session:
                    self.session = session
                    return True
                waited = time.monotonic() - start
                bound = CLOSING_HOLDER_WAIT_S if peer_has_closed(holder.sock) else HOLDER_GRACE_S
                if waited >= bound:
                    break
                self._cond.wait(min(bound - waited, 0.02))
        log.warning(
            "refusing a second %sclient from %s:%d: a %sclient is already connected "
            "(one at a time)",
            self.kind,
            session.peer[0],
            session.peer[1],
            self.kind,
        )
        return False

    def holds(self, session: Session) -> bool:
        """Whether ``session`` is the connected client."""
        with self._cond:
            return self.session is session

    def release(self, session: Session) -> None:
        """``session`` ended: the slot is free (unless another already holds it)."""
        with self._cond:
            if session in self._unconnected:
                self._unconnected.remove(session)
            if self.session is session:
                self.session = None
                self._cond.notify_all()

    def close(self) -> None:
        """Server shutdown: close every connection."""
        with self._cond:
            sessions = [*self._unconnected, *([self.session] if self.session else [])]
        for session in sessions:
            session.close()


def stop_serving(
    running: threading.Event,
    slot: ClientSlot,
    threads: list[threading.Thread],
    *sockets: socket.socket,
) -> None:
    """A server's shutdown: stop its loops, close its clients, join its threads, close sockets."""
    running.clear()
    slot.close()
    for thread in threads:
        thread.join(timeout=2.0)
    for sock in sockets:
        sock.close()
