"""TCP messages of robot server v10 (docs/wire-protocol.md §2-§6): constants, enums,
headers, replies."""

from __future__ import annotations

import struct

import pytest

from franka_sim_gym.fci.wire.protocol import (
    COMMAND_PORT,
    HEADER,
    MAX_MESSAGE_SIZE,
    VERSION,
    AutomaticErrorRecoveryStatus,
    Command,
    ConnectStatus,
    GetterStatus,
    MoveStatus,
    ProtocolError,
    SetterStatus,
    StopMoveStatus,
    decode_connect_reply,
    decode_reply,
    encode_connect_reply,
    encode_reply,
    encode_request,
    encode_robot_model_reply,
)

# ---------------------------------------------------------------------------
# Constants and enums (§2.1, §3, §3.1)
# ---------------------------------------------------------------------------


def test_version_port_and_header_layout():
    assert VERSION == 10
    assert COMMAND_PORT == 1337
    assert HEADER.size == 12
    assert HEADER.pack(1, 2, 3) == b"\x01\x00\x00\x00\x02\x00\x00\x00\x03\x00\x00\x00"
    assert MAX_MESSAGE_SIZE == 1 << 20


def test_command_ids():
    assert [(c.name, c.value) for c in Command] == [
        ("kConnect", 0),
        ("kMove", 1),
        ("kStopMove", 2),
        ("kSetCollisionBehavior", 3),
        ("kSetJointImpedance", 4),
        ("kSetCartesianImpedance", 5),
        ("kSetGuidingMode", 6),
        ("kSetEEToK", 7),
        ("kSetNEToEE", 8),
        ("kSetLoad", 9),
        ("kAutomaticErrorRecovery", 10),
        ("kGetRobotModel", 11),
    ]


def test_status_enums_follow_the_spec_table():
    assert [m.name for m in GetterStatus] == [
        "kSuccess",
        "kCommandNotPossibleRejected",
        "kCommandRejectedDueToActivatedSafetyFunctions",
    ]
    assert [m.name for m in SetterStatus] == [
        "kSuccess",
        "kCommandNotPossibleRejected",
        "kInvalidArgumentRejected",
        "kCommandRejectedDueToActivatedSafetyFunctions",
    ]
    assert [m.name for m in ConnectStatus] == ["kSuccess", "kIncompatibleLibraryVersion"]
    assert [m.name for m in MoveStatus] == [
        "kSuccess",
        "kMotionStarted",
        "kPreempted",
        "kPreemptedDueToActivatedSafetyFunctions",
        "kCommandRejectedDueToActivatedSafetyFunctions",
        "kCommandNotPossibleRejected",
        "kStartAtSingularPoseRejected",
        "kInvalidArgumentRejected",
        "kReflexAborted",
        "kEmergencyAborted",
        "kInputErrorAborted",
        "kAborted",
    ]
    assert [m.name for m in StopMoveStatus] == [
        "kSuccess",
        "kCommandNotPossibleRejected",
        "kCommandRejectedDueToActivatedSafetyFunctions",
        "kEmergencyAborted",
        "kReflexAborted",
        "kAborted",
    ]
    assert [m.name for m in AutomaticErrorRecoveryStatus] == [
        "kSuccess",
        "kCommandNotPossibleRejected",
        "kCommandRejectedDueToActivatedSafetyFunctions",
        "kManualErrorRecoveryRequiredRejected",
        "kReflexAborted",
        "kEmergencyAborted",
        "kAborted",
    ]
    for enum in (
        GetterStatus,
        SetterStatus,
        ConnectStatus,
        MoveStatus,
        StopMoveStatus,
        AutomaticErrorRecoveryStatus,
    ):
        assert [m.value for m in enum] == list(range(len(enum)))


def test_encode_request_header_counts_the_payload():
    message = encode_request(Command.kStopMove, 77)
    assert message == HEADER.pack(2, 77, 12)
    assert HEADER.unpack_from(encode_request(9, 1, bytes(104))) == (9, 1, 116)


# ---------------------------------------------------------------------------
# Replies (§2.1, §4, §6)
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("command", list(Command))
def test_status_reply_is_13_bytes_and_echoes_command_and_id(command):
    reply = encode_reply(command, 0xDEADBEEF, 5)
    assert len(reply) == 13
    assert HEADER.unpack_from(reply) == (command, 0xDEADBEEF, 13)
    assert reply[12] == 5
    assert decode_reply(reply[12:]) == (5, b"")


def test_connect_reply_is_15_bytes_with_status_then_server_version():
    reply = encode_connect_reply(3, ConnectStatus.kIncompatibleLibraryVersion)
    assert len(reply) == 15
    assert HEADER.unpack_from(reply) == (0, 3, 15)
    assert reply[12] == 1
    assert reply[13:15] == b"\x0a\x00"
    assert decode_connect_reply(reply[12:]) == (1, 10)
    assert decode_connect_reply(encode_connect_reply(0, 0, version=9)[12:]) == (0, 9)


def test_robot_model_reply_is_13_plus_n_utf8_bytes_without_terminator():
    urdf = '<robot name="fr3">\u00b5</robot>'  # one 2-byte UTF-8 character
    n = len(urdf.encode("utf-8"))
    assert n == len(urdf) + 1
    reply = encode_robot_model_reply(1, GetterStatus.kSuccess, urdf)
    assert len(reply) == 13 + n
    assert HEADER.unpack_from(reply) == (11, 1, 13 + n)
    assert reply[12] == 0
    assert reply[13:].decode("utf-8") == urdf


def test_status_outside_u8_cannot_be_encoded():
    with pytest.raises(struct.error):
        encode_reply(1, 0, 256)


def test_empty_reply_payload_is_a_protocol_error():
    with pytest.raises(ProtocolError):
        decode_reply(b"")
    with pytest.raises(ProtocolError, match="truncated Connect reply"):
        decode_connect_reply(b"\x00\x0a")
