"""TCP messages of robot server v10 (port 1337): requests, replies (framing: fci/wire/framing.py;
the request payloads' layouts and their decoding: fci/wire/request_payloads.py, re-exported here).

Spec: docs/wire-protocol.md §2 (framing), §3 (commands, status enums, payloads),
§4 (Connect), §5.1 (Move), §6 (GetRobotModel). Everything is little-endian and
packed. This module only knows layouts: it never judges values (range checks,
NaN, version mismatch are the controller's business).
"""

from __future__ import annotations

import math
import struct

from .framing import HEADER, MAX_MESSAGE_SIZE, Frame, FrameDecoder, FramingError
from .request_payloads import (
    REQUEST_SIZE,
    AutomaticErrorRecoveryRequest,
    ConnectRequest,
    GetRobotModelRequest,
    MoveRequest,
    ProtocolError,
    Request,
    SetCartesianImpedanceRequest,
    SetCollisionBehaviorRequest,
    SetEEToKRequest,
    SetGuidingModeRequest,
    SetJointImpedanceRequest,
    SetLoadRequest,
    SetNEToEERequest,
    StopMoveRequest,
    decode_request,
)
from .statuses import (
    AutomaticErrorRecoveryStatus,
    Command,
    ConnectStatus,
    GetterStatus,
    MoveStatus,
    SetterStatus,
    StopMoveStatus,
)

__all__ = [
    "VERSION",
    "COMMAND_PORT",
    "HEADER",
    "MAX_MESSAGE_SIZE",
    "DEFAULT_DEVIATION",
    "Command",
    "ConnectStatus",
    "MoveStatus",
    "StopMoveStatus",
    "SetterStatus",
    "GetterStatus",
    "AutomaticErrorRecoveryStatus",
    "REQUEST_SIZE",
    "ProtocolError",
    "ConnectRequest",
    "MoveRequest",
    "StopMoveRequest",
    "SetCollisionBehaviorRequest",
    "SetJointImpedanceRequest",
    "SetCartesianImpedanceRequest",
    "SetGuidingModeRequest",
    "SetEEToKRequest",
    "SetNEToEERequest",
    "SetLoadRequest",
    "AutomaticErrorRecoveryRequest",
    "GetRobotModelRequest",
    "Request",
    "decode_request",
    "encode_request",
    "encode_message",
    "encode_connect_request",
    "encode_move_request",
    "encode_reply",
    "encode_connect_reply",
    "encode_robot_model_reply",
    "decode_reply",
    "decode_connect_reply",
    "Frame",
    "FramingError",
    "FrameDecoder",
]

VERSION = 10
COMMAND_PORT = 1337
# §5.1: libfranka always sends {translation 10.0 m, rotation 3.12 rad, elbow 2 pi}.
DEFAULT_DEVIATION: tuple[float, float, float] = (10.0, 3.12, 2.0 * math.pi)

_STATUS = struct.Struct("<B")
_U16 = struct.Struct("<H")


# ---------------------------------------------------------------------------
# Encoding (requests for tests / a raw test client; replies for the server).
# ---------------------------------------------------------------------------


def encode_request(command: int, command_id: int, payload: bytes = b"") -> bytes:
    """Header (§2.1, size = 12 + len(payload)) followed by the payload."""
    return HEADER.pack(command, command_id, HEADER.size + len(payload)) + bytes(payload)


def encode_message(request: Request, command_id: int) -> bytes:
    """A complete request message for a request dataclass."""
    return encode_request(request.COMMAND, command_id, request.payload())


def encode_connect_request(command_id: int = 0, udp_port: int = 0, version: int = VERSION) -> bytes:
    """§4: the 16-byte Connect request."""
    return encode_message(ConnectRequest(version=version, udp_port=udp_port), command_id)


def encode_move_request(
    command_id: int,
    controller_mode: int,
    motion_generator_mode: int,
    *,
    maximum_path_deviation: tuple[float, ...] = DEFAULT_DEVIATION,
    maximum_goal_pose_deviation: tuple[float, ...] = DEFAULT_DEVIATION,
    use_async_motion_generator: bool = False,
    maximum_velocity: tuple[float, ...] = (0.0,) * 7,
) -> bytes:
    """§5.1: the 125-byte Move request, with libfranka's defaults."""
    request = MoveRequest(
        controller_mode=controller_mode,
        motion_generator_mode=motion_generator_mode,
        maximum_path_deviation=tuple(maximum_path_deviation),
        maximum_goal_pose_deviation=tuple(maximum_goal_pose_deviation),
        use_async_motion_generator=use_async_motion_generator,
        maximum_velocity=tuple(maximum_velocity),
    )
    return encode_message(request, command_id)


def encode_reply(command: int, command_id: int, status: int, payload: bytes = b"") -> bytes:
    """§2.1: reply header (size = 13 + len(payload)), u8 status, payload."""
    body = _STATUS.pack(status) + bytes(payload)
    return HEADER.pack(command, command_id, HEADER.size + len(body)) + body


def encode_connect_reply(command_id: int, status: int, version: int = VERSION) -> bytes:
    """§4: 15 bytes: header, status u8, the server's version u16."""
    return encode_reply(Command.kConnect, command_id, status, _U16.pack(version))


def encode_robot_model_reply(command_id: int, status: int, urdf: str) -> bytes:
    """§6: 13 + N bytes: header, status u8, the URDF as UTF-8 (no prefix, no NUL)."""
    return encode_reply(Command.kGetRobotModel, command_id, status, urdf.encode("utf-8"))


def decode_reply(payload: bytes) -> tuple[int, bytes]:
    """Split a reply payload into (status u8, rest). ``ProtocolError`` if empty."""
    if len(payload) < _STATUS.size:
        raise ProtocolError("reply payload without a status byte")
    return payload[0], bytes(payload[1:])


def decode_connect_reply(payload: bytes) -> tuple[int, int]:
    """§4: (status, server version) of a Connect reply payload (trailing bytes ignored)."""
    if len(payload) < _STATUS.size + _U16.size:
        raise ProtocolError(f"truncated Connect reply payload: {len(payload)} bytes, expected 3")
    return payload[0], _U16.unpack_from(payload, 1)[0]
