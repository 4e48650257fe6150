"""One libfranka client's TCP connection on port 1337: decoding and dispatch.

The connection's reader thread decodes frames (:mod:`~franka_sim_gym.server.connection`)
and this session hands each request to its host, the robot server, which applies
it on the tick thread at a cycle boundary. Every request is answered (libfranka
has no reply timeout: a silent server hangs it), with the status the robot would
give; malformed input is logged with a named reason. Replies are queued on the
connection's outbox: answering never waits on the client.
"""

from __future__ import annotations

import logging
import socket
from typing import Protocol

from ..fci.wire import protocol as p
from .tcp_session import SlotHost, TcpSession

log = logging.getLogger("franka_sim_gym.server")

_SETTERS = (
    p.Command.kSetCollisionBehavior,
    p.Command.kSetJointImpedance,
    p.Command.kSetCartesianImpedance,
    p.Command.kSetGuidingMode,
    p.Command.kSetEEToK,
    p.Command.kSetNEToEE,
    p.Command.kSetLoad,
)

#: What to answer a request whose payload could not be decoded: the status each
#: command's enum has for a bad argument (libfranka
#: ``common/include/research_interface/robot/service_types.h``).
INVALID_ARGUMENT = {
    p.Command.kConnect: p.ConnectStatus.kIncompatibleLibraryVersion,
    p.Command.kMove: p.MoveStatus.kInvalidArgumentRejected,
    p.Command.kStopMove: p.StopMoveStatus.kCommandNotPossibleRejected,
    p.Command.kAutomaticErrorRecovery: p.AutomaticErrorRecoveryStatus.kCommandNotPossibleRejected,
    p.Command.kGetRobotModel: p.GetterStatus.kCommandNotPossibleRejected,
    **{c: p.SetterStatus.kInvalidArgumentRejected for c in _SETTERS},
}

#: What to answer a request sent before Connect: each command's own
#: kCommandNotPossibleRejected (service_types.h; Move's is 5, every other's 1).
#: libfranka never sends one (its Robot opens with Connect: src/robot_impl.cpp).
NOT_POSSIBLE = {
    p.Command.kMove: p.MoveStatus.kCommandNotPossibleRejected,
    p.Command.kStopMove: p.StopMoveStatus.kCommandNotPossibleRejected,
    p.Command.kAutomaticErrorRecovery: p.AutomaticErrorRecoveryStatus.kCommandNotPossibleRejected,
    p.Command.kGetRobotModel: p.GetterStatus.kCommandNotPossibleRejected,
    **{c: p.SetterStatus.kCommandNotPossibleRejected for c in _SETTERS},
}


class SessionHost(SlotHost, Protocol):
    """What a session needs of its server (the robot server is one)."""

    urdf: str

    def submit_request(
        self, session: ClientSession, command: p.Command, command_id: int, request: object
    ) -> None: ...


class ClientSession(TcpSession):
    """The TCP side of one client of the arm (connected once its Connect succeeded)."""

    host: SessionHost

    def __init__(self, host: SessionHost, sock: socket.socket, peer: tuple[str, int]) -> None:
        self._decoder = p.FrameDecoder()
        super().__init__(host, sock, peer, "", log, self._decoder.feed, self._handle)

    def reply(self, command: int, command_id: int, status: int) -> None:
        self.send(p.encode_reply(command, command_id, int(status)))

    # -- the reader thread ------------------------------------------------------------------

    def _handle(self, item: p.Frame | p.FramingError) -> None:
        if isinstance(item, p.FramingError):
            log.warning(
                "client %s: bad TCP frame (command %d, id %d): %s",
                self.peer,
                item.command,
                item.command_id,
                item.reason,
            )
            return
        self._dispatch(item)

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
        if command != p.Command.kConnect and self.udp_port is None:
            status = NOT_POSSIBLE[command]
            log.warning(
                "client %s: %s before Connect: answered %s", self.peer, command.name, status.name
            )
            if command == p.Command.kGetRobotModel:
                self.send(p.encode_robot_model_reply(frame.command_id, int(status), ""))
            else:
                self.reply(frame.command, frame.command_id, status)
            return
        try:
            request = p.decode_request(frame.command, frame.payload)
        except p.ProtocolError as exc:
            status = INVALID_ARGUMENT[command]
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
                    frame.command_id, int(p.GetterStatus.kSuccess), self.host.urdf
                )
            )
        else:
            self.host.submit_request(self, command, frame.command_id, request)

    def _connect(self, command_id: int, request: p.ConnectRequest) -> None:
        if request.version != p.VERSION:
            # libfranka compares nothing itself: the server decides (src/network.h, connect).
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
        success = p.encode_connect_reply(command_id, int(p.ConnectStatus.kSuccess))
        self.connect(success, request.udp_port)
