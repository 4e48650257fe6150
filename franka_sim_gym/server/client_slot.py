"""One client at a time on a listening TCP socket (the arm's port and the hand's alike).

A second client is refused with a clear log line while the first keeps running;
when the first goes away the slot is free for the next.
"""

from __future__ import annotations

import logging
import socket
import threading
from collections.abc import Callable
from typing import Protocol

log = logging.getLogger("franka_sim_gym.server")


class Session(Protocol):
    thread: threading.Thread

    def close(self) -> None: ...


class ClientSlot:
    """Holds the one connected session of a server.

    Args:
        kind: how the log names the client ("" for the arm, "gripper " for the hand).
        make_session: builds the session for an accepted (socket, peer).
    """

    def __init__(self, kind: str, make_session: Callable[[socket.socket, tuple], Session]):
        self.kind = kind
        self.make_session = make_session
        self._lock = threading.Lock()
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
            with self._lock:
                session = None if self.session is not None else self.make_session(sock, peer)
                if session is not None:
                    self.session = session
            if session is None:
                log.warning(
                    "refusing a second %sclient from %s:%d: a %sclient is already connected "
                    "(one at a time)",
                    self.kind,
                    peer[0],
                    peer[1],
                    self.kind,
                )
                sock.close()
                continue
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            session.thread.start()

    def release(self, session: Session) -> None:
        """``session`` ended: the slot is free (unless another already holds it)."""
        with self._lock:
            if self.session is session:
                self.session = None

    def close(self) -> None:
        """Server shutdown: close the connected session, if any."""
        with self._lock:
            session = self.session
        if session is not None:
            session.close()


def stop_serving(
    running: threading.Event,
    slot: ClientSlot,
    threads: list[threading.Thread],
    *sockets: socket.socket,
) -> None:
    """A server's shutdown: stop its loops, close its client, join its threads, close sockets."""
    running.clear()
    slot.close()
    for thread in threads:
        thread.join(timeout=2.0)
    for sock in sockets:
        sock.close()
