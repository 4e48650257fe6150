"""One libfranka client's TCP connection on port 1337: framing, decoding, dispatch.

A session thread reads frames, decodes them and hands each request to the
server, which applies it on the tick thread at a cycle boundary. Every request
is answered (libfranka has no reply timeout: a silent server hangs it), with
the status the robot would give; malformed input is logged with a named reason.
"""

from __future__ import annotations

import logging
import socket
import threading
from typing import TYPE_CHECKING

from ..fci import protocol as p

if TYPE_CHECKING:
    from .robot_server import RobotServer

log = logging.getLogger("franka_sim_gym.server")

#: What to answer a request whose payload could not be decoded: the status
#: each command's enum has for a bad argument (fci-wire-protocol.md §3.1).
_INVALID_ARGUMENT = {
    p.Command.kConnect: p.ConnectStatus.kIncompatibleLibraryVersion,
    p.Command.kMove: p.MoveStatus.kInvalidArgumentRejected,
    p.Command.kStopMove: p.StopMoveStatus.kCommandNotPossibleRejected,
    p.Command.kAutomaticErrorRecovery: p.AutomaticErrorRecoveryStatus.kCommandNotPossibleRejected,
    p.Command.kGetRobotModel: p.GetterStatus.kCommandNotPossibleRejected,
}


class ClientSession:
    """The TCP side of one connected client."""

    def __init__(self, server: RobotServer, sock: socket.socket, peer: tuple[str, int]) -> None:
        self.server = server
        self.sock = sock
        self.peer = peer
        self.udp_port: int | None = None
        self.closed = threading.Event()
        self._send_lock = threading.Lock()
        self._decoder = p.FrameDecoder()
        self.thread = threading.Thread(target=self._run, name=f"fci-session-{peer}", daemon=True)

    # -- sending ----------------------------------------------------------------------------

    def send(self, data: bytes) -> None:
        """Send one reply; a vanished client is noticed by the reader, not here."""
        with self._send_lock:
            try:
                self.sock.sendall(data)
            except OSError as exc:
                log.info("client %s: reply not delivered (%s)", self.peer, exc)

    def reply(self, command: int, command_id: int, status: int) -> None:
        self.send(p.encode_reply(command, command_id, int(status)))

    # -- reading ----------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            while not self.closed.is_set():
                try:
                    data = self.sock.recv(65536)
                except OSError as exc:
                    log.info("client %s: connection error (%s)", self.peer, exc)
                    break
                if not data:
                    break
                for item in self._decoder.feed(data):
                    if isinstance(item, p.FramingError):
                        log.warning(
                            "client %s: bad TCP frame (command %d, id %d): %s",
                            self.peer,
                            item.command,
                            item.command_id,
                            item.reason,
                        )
                        continue
                    self._dispatch(item)
        finally:
            self.closed.set()
            try:
                self.sock.close()
            except OSError:
                pass
            self.server.session_closed(self)

    def _dispatch(self, frame: p.Frame) -> None:
        try:
            command = p.Command(frame.command)
        except ValueError:
            log.warning(
                "client %s: unknown command id %d (request id %d): answered "
                "kCommandNotPossibleRejected",
                self.peer,
                frame.command,
                frame.command_id,
            )
            self.reply(frame.command, frame.command_id, 1)
            return
        try:
            request = p.decode_request(frame.command, frame.payload)
        except p.ProtocolError as exc:
            status = _INVALID_ARGUMENT.get(command, p.SetterStatus.kInvalidArgumentRejected)
            log.warning("client %s: %s: answered %s", self.peer, exc.reason, status.name)
            if command == p.Command.kConnect:
                self.send(p.encode_connect_reply(frame.command_id, int(status)))
            else:
                self.reply(frame.command, frame.command_id, status)
            return
        if command == p.Command.kConnect:
            self._connect(frame.command_id, request)
        elif command == p.Command.kGetRobotModel:
            self.send(
                p.encode_robot_model_reply(
                    frame.command_id, int(p.GetterStatus.kSuccess), self.server.urdf
                )
            )
        elif self.udp_port is None:
            log.warning(
                "client %s: %s before Connect: answered kCommandNotPossibleRejected",
                self.peer,
                command.name,
            )
            self.reply(frame.command, frame.command_id, 1)
        else:
            self.server.submit_request(self, command, frame.command_id, request)

    def _connect(self, command_id: int, request: p.ConnectRequest) -> None:
        if request.version != p.VERSION:
            # libfranka compares nothing itself: the server decides (wire spec §4).
            log.warning(
                "client %s: library version %d is not %d: answered kIncompatibleLibraryVersion",
                self.peer,
                request.version,
                p.VERSION,
            )
            self.send(
                p.encode_connect_reply(command_id, int(p.ConnectStatus.kIncompatibleLibraryVersion))
            )
            return
        self.send(p.encode_connect_reply(command_id, int(p.ConnectStatus.kSuccess)))
        self.udp_port = request.udp_port
        log.info("client %s connected (UDP port %d)", self.peer, request.udp_port)
        self.server.client_connected(self)

    def close(self) -> None:
        """Close the connection (server shutdown)."""
        self.closed.set()
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
