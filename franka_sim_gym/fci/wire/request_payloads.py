"""The request payloads of robot server v10 (port 1337): one frozen dataclass per command,
its wire layout, and the decoding of a payload (docs/wire-protocol.md §3, §4, §5.1, §6).

Little-endian and packed. Layouts only: values are returned raw, never judged (range
checks, NaN, a version mismatch are the controller's business). The messages around
them (headers, replies, the encoders) are ``fci/wire/protocol.py``'s, which re-exports
everything here.
"""

from __future__ import annotations

import struct
from dataclasses import astuple, dataclass, fields
from typing import ClassVar

from .framing import HEADER
from .statuses import Command

# §3: total request sizes, header included.
REQUEST_SIZE: dict[Command, int] = {
    Command.kConnect: 16,
    Command.kMove: 125,
    Command.kStopMove: 12,
    Command.kSetCollisionBehavior: 428,
    Command.kSetJointImpedance: 68,
    Command.kSetCartesianImpedance: 60,
    Command.kSetGuidingMode: 19,
    Command.kSetEEToK: 140,
    Command.kSetNEToEE: 140,
    Command.kSetLoad: 116,
    Command.kAutomaticErrorRecovery: 12,
    Command.kGetRobotModel: 12,
}


class ProtocolError(Exception):
    """A message that does not fit the v10 layout; ``reason`` says what is wrong."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _name(command: Command) -> str:
    """``Command.kSetLoad`` -> ``"SetLoad"`` for messages."""
    return command.name[1:]


# ---------------------------------------------------------------------------
# Request payloads (§3.2, §4, §5.1). Each class declares its wire layout as
# ``_LAYOUT``: one (struct code, count) per dataclass field, in field order;
# count None = scalar field, otherwise a tuple of that many values.
# ---------------------------------------------------------------------------


class _Payload:
    """Layout-driven encode/decode shared by the request dataclasses."""

    COMMAND: ClassVar[Command]
    _LAYOUT: ClassVar[tuple[tuple[str, int | None], ...]] = ()
    _STRUCT: ClassVar[struct.Struct]

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        codes = "".join(f"{count or ''}{code}" for code, count in cls._LAYOUT)
        cls._STRUCT = struct.Struct("<" + codes)
        assert cls._STRUCT.size == REQUEST_SIZE[cls.COMMAND] - HEADER.size, cls

    def payload(self) -> bytes:
        """The payload bytes (without header) of this request."""
        flat: list[object] = []
        for f, (_, count), value in zip(fields(self), self._LAYOUT, astuple(self), strict=True):
            if count is None:
                flat.append(value)
                continue
            value = tuple(value)
            if len(value) != count:
                raise ValueError(
                    f"{type(self).__name__}.{f.name}: expected {count} values, got {len(value)}"
                )
            flat.extend(value)
        try:
            return self._STRUCT.pack(*flat)
        except struct.error as exc:
            raise ValueError(f"{type(self).__name__}: {exc}") from exc

    @classmethod
    def _decode(cls, payload: bytes) -> _Payload:
        values = cls._STRUCT.unpack(payload)
        kwargs: dict[str, object] = {}
        i = 0
        for f, (_, count) in zip(fields(cls), cls._LAYOUT, strict=True):  # type: ignore[arg-type]
            if count is None:
                kwargs[f.name] = values[i]
                i += 1
            else:
                kwargs[f.name] = tuple(values[i : i + count])
                i += count
        return cls(**kwargs)


@dataclass(frozen=True)
class ConnectRequest(_Payload):
    """§4: abs 12 version u16, abs 14 udp_port u16."""

    COMMAND: ClassVar[Command] = Command.kConnect
    _LAYOUT: ClassVar = (("H", None), ("H", None))
    version: int
    udp_port: int


@dataclass(frozen=True)
class MoveRequest(_Payload):
    """§5.1: Move. Modes are raw request numbers (``wire.MoveControllerMode`` etc.)."""

    COMMAND: ClassVar[Command] = Command.kMove
    _LAYOUT: ClassVar = (("I", None), ("I", None), ("d", 3), ("d", 3), ("?", None), ("d", 7))
    controller_mode: int
    motion_generator_mode: int
    maximum_path_deviation: tuple[float, ...]  # translation m, rotation rad, elbow rad
    maximum_goal_pose_deviation: tuple[float, ...]
    use_async_motion_generator: bool
    maximum_velocity: tuple[float, ...]  # rad/s, 7 joints


@dataclass(frozen=True)
class StopMoveRequest(_Payload):
    """§3: StopMove, no payload."""

    COMMAND: ClassVar[Command] = Command.kStopMove


@dataclass(frozen=True)
class SetCollisionBehaviorRequest(_Payload):
    """§3.2: eight threshold arrays, torques f64[7] (Nm) then forces f64[6] (N / Nm)."""

    COMMAND: ClassVar[Command] = Command.kSetCollisionBehavior
    _LAYOUT: ClassVar = (("d", 7),) * 4 + (("d", 6),) * 4
    lower_torque_thresholds_acceleration: tuple[float, ...]
    upper_torque_thresholds_acceleration: tuple[float, ...]
    lower_torque_thresholds_nominal: tuple[float, ...]
    upper_torque_thresholds_nominal: tuple[float, ...]
    lower_force_thresholds_acceleration: tuple[float, ...]
    upper_force_thresholds_acceleration: tuple[float, ...]
    lower_force_thresholds_nominal: tuple[float, ...]
    upper_force_thresholds_nominal: tuple[float, ...]


@dataclass(frozen=True)
class SetJointImpedanceRequest(_Payload):
    """§3.2: K_theta f64[7], Nm/rad."""

    COMMAND: ClassVar[Command] = Command.kSetJointImpedance
    _LAYOUT: ClassVar = (("d", 7),)
    K_theta: tuple[float, ...]


@dataclass(frozen=True)
class SetCartesianImpedanceRequest(_Payload):
    """§3.2: K_x f64[6] (N/m x3, Nm/rad x3), in frame K."""

    COMMAND: ClassVar[Command] = Command.kSetCartesianImpedance
    _LAYOUT: ClassVar = (("d", 6),)
    K_x: tuple[float, ...]


@dataclass(frozen=True)
class SetGuidingModeRequest(_Payload):
    """§3.2: guiding_mode bool[6] (x,y,z,R,P,Y unlocked), nullspace bool (elbow free)."""

    COMMAND: ClassVar[Command] = Command.kSetGuidingMode
    _LAYOUT: ClassVar = (("?", 6), ("?", None))
    guiding_mode: tuple[bool, ...]
    nullspace: bool


@dataclass(frozen=True)
class SetEEToKRequest(_Payload):
    """§3.2: EE_T_K f64[16], column-major."""

    COMMAND: ClassVar[Command] = Command.kSetEEToK
    _LAYOUT: ClassVar = (("d", 16),)
    EE_T_K: tuple[float, ...]


@dataclass(frozen=True)
class SetNEToEERequest(_Payload):
    """§3.2: NE_T_EE f64[16], column-major."""

    COMMAND: ClassVar[Command] = Command.kSetNEToEE
    _LAYOUT: ClassVar = (("d", 16),)
    NE_T_EE: tuple[float, ...]


@dataclass(frozen=True)
class SetLoadRequest(_Payload):
    """§3.2: m_load f64 kg, F_x_Cload f64[3] m, I_load f64[9] kg m^2 (column-major)."""

    COMMAND: ClassVar[Command] = Command.kSetLoad
    _LAYOUT: ClassVar = (("d", None), ("d", 3), ("d", 9))
    m_load: float
    F_x_Cload: tuple[float, ...]
    I_load: tuple[float, ...]


@dataclass(frozen=True)
class AutomaticErrorRecoveryRequest(_Payload):
    """§3: AutomaticErrorRecovery, no payload."""

    COMMAND: ClassVar[Command] = Command.kAutomaticErrorRecovery


@dataclass(frozen=True)
class GetRobotModelRequest(_Payload):
    """§6: GetRobotModel, no payload."""

    COMMAND: ClassVar[Command] = Command.kGetRobotModel


Request = (
    ConnectRequest
    | MoveRequest
    | StopMoveRequest
    | SetCollisionBehaviorRequest
    | SetJointImpedanceRequest
    | SetCartesianImpedanceRequest
    | SetGuidingModeRequest
    | SetEEToKRequest
    | SetNEToEERequest
    | SetLoadRequest
    | AutomaticErrorRecoveryRequest
    | GetRobotModelRequest
)

_REQUEST_CLASSES: dict[Command, type[_Payload]] = {
    cls.COMMAND: cls
    for cls in (
        ConnectRequest,
        MoveRequest,
        StopMoveRequest,
        SetCollisionBehaviorRequest,
        SetJointImpedanceRequest,
        SetCartesianImpedanceRequest,
        SetGuidingModeRequest,
        SetEEToKRequest,
        SetNEToEERequest,
        SetLoadRequest,
        AutomaticErrorRecoveryRequest,
        GetRobotModelRequest,
    )
}
assert set(_REQUEST_CLASSES) == set(Command)


def decode_request(command: int, payload: bytes) -> Request:
    """Decode the payload (bytes after the header) of a request with this command id.

    Raises ``ProtocolError`` for an unknown id or a payload whose length is not
    exactly the command's (§3). Values are returned raw, never judged.
    """
    try:
        cmd = Command(command)
    except ValueError:
        raise ProtocolError(f"unknown command id {command}") from None
    expected = REQUEST_SIZE[cmd] - HEADER.size
    n = len(payload)
    if n < expected:
        raise ProtocolError(f"truncated {_name(cmd)} payload: {n} bytes, expected {expected}")
    if n > expected:
        raise ProtocolError(f"oversized {_name(cmd)} payload: {n} bytes, expected {expected}")
    return _REQUEST_CLASSES[cmd]._decode(payload)  # type: ignore[return-value]
