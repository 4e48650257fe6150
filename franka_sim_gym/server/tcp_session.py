"""What the arm's and the hand's TCP sessions share: their connection and a valid Connect.

A session decodes its protocol's frames and dispatches them: the arm's
(:class:`~franka_sim_gym.server.session.ClientSession`, port 1337) and the hand's
(:class:`~franka_sim_gym.server.gripper_server.GripperSession`, port 1338). Under
each is one :class:`~franka_sim_gym.server.connection.Connection` (reader thread,
outbox, connect deadline), and both end a valid Connect the same way: the client
slot is claimed first (:mod:`franka_sim_gym.server.client_slot`), then the reply
queued and the server told where to send its UDP states.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Callable, Iterable
from typing import Protocol

from .connection import Connection


class SlotHost(Protocol):
    """What a session needs of its server (the robot server and the gripper server)."""

    def claim(self, session: TcpSession) -> bool: ...

    def client_connected(self, session: TcpSession) -> None: ...

    def session_closed(self, session: TcpSession) -> None: ...


class TcpSession:
    """The TCP side of one client (connected once its Connect succeeded).

    Args:
        host: its server: holds the client slot, is told of a Connect and of the end.
        sock: the accepted socket.
        peer: its (address, port).
        kind: how the log names the client ("" for the arm, "gripper " for the hand).
        log: the server's logger.
        feed: the protocol's frame decoder (bytes in, frames or framing errors out).
        handle: called on the reader thread with each decoded item.
    """

    def __init__(
        self,
        host: SlotHost,
        sock: socket.socket,
        peer: tuple[str, int],
        kind: str,
        log: logging.Logger,
        feed: Callable[[bytes], Iterable],
        handle: Callable[[object], None],
    ) -> None:
        self.host = host
        #: The UDP port the client's Connect named: None until a Connect succeeded.
        self.udp_port: int | None = None
        self._kind = kind
        self._log = log
        self.connection = Connection(
            sock,
            peer,
            f"{kind}client {peer[0]}:{peer[1]}",
            log,
            feed,
            handle,
            lambda: host.session_closed(self),
        )

    @property
    def sock(self) -> socket.socket:
        return self.connection.sock

    @property
    def peer(self) -> tuple[str, int]:
        return self.connection.peer

    def start(self) -> None:
        self.connection.start()

    def close(self) -> None:
        """Close the connection (server shutdown, or the client was refused)."""
        self.connection.close()

    def send(self, data: bytes) -> None:
        """Queue one reply; never blocks (a client that does not read is dropped)."""
        self.connection.send(data)

    def connect(self, reply: bytes, udp_port: int) -> None:
        """End a valid Connect: claim the slot (refused: the connection closes), queue
        ``reply`` (the protocol's success), lift the connect deadline, tell the host."""
        if not self.host.claim(self):
            self.close()
            return
        self.udp_port = udp_port
        self.send(reply)
        self.connection.mark_connected()
        self._log.info("%sclient %s connected (UDP port %d)", self._kind, self.peer, udp_port)
        self.host.client_connected(self)
