"""TCP messages of robot server v10 (docs/wire-protocol.md §2-§6) and our framing contract."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci.protocol import (
    COMMAND_PORT,
    HEADER,
    MAX_MESSAGE_SIZE,
    REQUEST_SIZE,
    VERSION,
    AutomaticErrorRecoveryRequest,
    AutomaticErrorRecoveryStatus,
    Command,
    ConnectRequest,
    ConnectStatus,
    Frame,
    FrameDecoder,
    FramingError,
    GetRobotModelRequest,
    GetterStatus,
    MoveRequest,
    MoveStatus,
    ProtocolError,
    SetCartesianImpedanceRequest,
    SetCollisionBehaviorRequest,
    SetEEToKRequest,
    SetGuidingModeRequest,
    SetJointImpedanceRequest,
    SetLoadRequest,
    SetNEToEERequest,
    SetterStatus,
    StopMoveRequest,
    StopMoveStatus,
    decode_connect_reply,
    decode_reply,
    decode_request,
    encode_connect_reply,
    encode_connect_request,
    encode_message,
    encode_move_request,
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


def test_request_sizes_are_the_spec_totals():
    assert REQUEST_SIZE == {
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


# ---------------------------------------------------------------------------
# Requests: round trip for every command (hypothesis), byte positions, errors
# ---------------------------------------------------------------------------

f64 = st.floats(allow_nan=False, width=64)
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)


def vec(n: int) -> st.SearchStrategy[tuple[float, ...]]:
    return st.tuples(*([f64] * n))


REQUESTS = st.one_of(
    st.builds(ConnectRequest, version=u16, udp_port=u16),
    st.builds(
        MoveRequest,
        controller_mode=u32,
        motion_generator_mode=u32,
        maximum_path_deviation=vec(3),
        maximum_goal_pose_deviation=vec(3),
        use_async_motion_generator=st.booleans(),
        maximum_velocity=vec(7),
    ),
    st.just(StopMoveRequest()),
    st.builds(SetCollisionBehaviorRequest, *([vec(7)] * 4 + [vec(6)] * 4)),
    st.builds(SetJointImpedanceRequest, K_theta=vec(7)),
    st.builds(SetCartesianImpedanceRequest, K_x=vec(6)),
    st.builds(
        SetGuidingModeRequest,
        guiding_mode=st.tuples(*([st.booleans()] * 6)),
        nullspace=st.booleans(),
    ),
    st.builds(SetEEToKRequest, EE_T_K=vec(16)),
    st.builds(SetNEToEERequest, NE_T_EE=vec(16)),
    st.builds(SetLoadRequest, m_load=f64, F_x_Cload=vec(3), I_load=vec(9)),
    st.just(AutomaticErrorRecoveryRequest()),
    st.just(GetRobotModelRequest()),
)


@settings(max_examples=300)
@given(request=REQUESTS, command_id=u32)
def test_every_request_round_trips_through_its_wire_message(request, command_id):
    message = encode_message(request, command_id)
    command, echoed_id, size = HEADER.unpack_from(message)
    assert command == request.COMMAND
    assert echoed_id == command_id
    assert size == len(message) == REQUEST_SIZE[request.COMMAND]
    decoded = decode_request(command, message[HEADER.size :])
    assert decoded == request
    assert type(decoded) is type(request)


def test_every_command_has_a_request_class_with_the_right_payload_size():
    empty = {Command.kStopMove, Command.kAutomaticErrorRecovery, Command.kGetRobotModel}
    for command in Command:
        if command in empty:
            request = decode_request(command, b"")
            assert request.COMMAND == command
            assert request.payload() == b""
        else:
            payload = bytes(REQUEST_SIZE[command] - 12)
            assert len(decode_request(command, payload).payload()) == len(payload)


def test_connect_request_puts_version_at_12_and_udp_port_at_14():
    message = encode_connect_request(command_id=0, udp_port=0xBEEF)
    assert len(message) == 16
    assert HEADER.unpack_from(message) == (0, 0, 16)
    assert message[12:14] == b"\x0a\x00"
    assert message[14:16] == b"\xef\xbe"


def test_move_request_fields_sit_at_the_spec_offsets():
    message = encode_move_request(
        5,
        2,
        4,
        maximum_path_deviation=(1.0, 2.0, 3.0),
        maximum_goal_pose_deviation=(4.0, 5.0, 6.0),
        use_async_motion_generator=True,
        maximum_velocity=(7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0),
    )
    assert len(message) == 125
    assert HEADER.unpack_from(message) == (1, 5, 125)
    assert struct.unpack_from("<II", message, 12) == (2, 4)
    assert struct.unpack_from("<6d", message, 20) == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    assert message[68] == 1
    assert struct.unpack_from("<7d", message, 69) == tuple(float(x) for x in range(7, 14))


def test_move_request_defaults_are_libfrankas_deviation_triple():
    request = decode_request(1, encode_move_request(0, 0, 0)[12:])
    assert request.maximum_path_deviation == (10.0, 3.12, 2 * math.pi)
    assert request.maximum_goal_pose_deviation == (10.0, 3.12, 2 * math.pi)
    assert request.use_async_motion_generator is False
    assert request.maximum_velocity == (0.0,) * 7


def test_set_load_fields_sit_at_abs_12_20_44():
    request = SetLoadRequest(1.5, (0.1, 0.2, 0.3), tuple(float(i) for i in range(9)))
    message = encode_message(request, 9)
    assert struct.unpack_from("<d", message, 12) == (1.5,)
    assert struct.unpack_from("<3d", message, 20) == (0.1, 0.2, 0.3)
    assert struct.unpack_from("<9d", message, 44) == request.I_load


def test_set_guiding_mode_nullspace_is_abs_18():
    message = encode_message(SetGuidingModeRequest((True,) + (False,) * 5, True), 0)
    assert len(message) == 19
    assert message[12:19] == b"\x01\x00\x00\x00\x00\x00\x01"


def test_set_collision_behavior_arrays_sit_at_their_offsets():
    arrays = [tuple(float(10 * k + j) for j in range(7 if k < 4 else 6)) for k in range(8)]
    message = encode_message(SetCollisionBehaviorRequest(*arrays), 3)
    for offset, array in zip((12, 68, 124, 180, 236, 284, 332, 380), arrays, strict=True):
        assert struct.unpack_from(f"<{len(array)}d", message, offset) == array


def test_values_are_not_judged_nan_and_odd_modes_pass_through():
    payload = struct.pack("<d3d9d", math.nan, math.inf, -0.0, 1e308, *([math.nan] * 9))
    request = decode_request(Command.kSetLoad, payload)
    assert math.isnan(request.m_load)
    assert request.F_x_Cload[0] == math.inf
    assert all(isinstance(x, float) for x in request.I_load)
    move = decode_request(Command.kMove, encode_move_request(0, 7, 99)[12:])
    assert (move.controller_mode, move.motion_generator_mode) == (7, 99)
    connect = decode_request(Command.kConnect, struct.pack("<HH", 9, 1234))
    assert connect == ConnectRequest(version=9, udp_port=1234)


def test_truncated_payload_names_the_command_and_both_sizes():
    with pytest.raises(ProtocolError) as info:
        decode_request(Command.kSetLoad, bytes(40))
    assert str(info.value) == "truncated SetLoad payload: 40 bytes, expected 104"
    assert info.value.reason == str(info.value)


@pytest.mark.parametrize("command", [c for c in Command if REQUEST_SIZE[c] > 12])
def test_any_payload_one_byte_short_is_truncated(command):
    expected = REQUEST_SIZE[command] - 12
    with pytest.raises(
        ProtocolError,
        match=rf"^truncated {command.name[1:]} payload: "
        rf"{expected - 1} bytes, expected {expected}$",
    ):
        decode_request(command, bytes(expected - 1))


@pytest.mark.parametrize("command", list(Command))
def test_any_payload_one_byte_long_is_rejected(command):
    expected = REQUEST_SIZE[command] - 12
    with pytest.raises(
        ProtocolError,
        match=rf"^oversized {command.name[1:]} payload: "
        rf"{expected + 1} bytes, expected {expected}$",
    ):
        decode_request(command, bytes(expected + 1))


@pytest.mark.parametrize("command", [12, 42, 0xFFFFFFFF])
def test_unknown_command_id_is_named(command):
    with pytest.raises(ProtocolError, match=rf"^unknown command id {command}$"):
        decode_request(command, b"")


def test_wrong_tuple_length_cannot_be_encoded():
    with pytest.raises(ValueError, match="K_theta"):
        SetJointImpedanceRequest((1.0,) * 6).payload()


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


# ---------------------------------------------------------------------------
# FrameDecoder (our robustness contract)
# ---------------------------------------------------------------------------

GOOD = [
    encode_connect_request(0, 40000),
    encode_request(Command.kGetRobotModel, 1),
    encode_move_request(2, 2, 4),
    encode_message(SetLoadRequest(0.5, (0.0, 0.0, 0.1), (0.0,) * 9), 3),
]


def _frame_of(message: bytes) -> Frame:
    command, command_id, _ = HEADER.unpack_from(message)
    return Frame(command, command_id, message[12:])


def test_several_frames_in_one_chunk_all_decode_in_order():
    decoder = FrameDecoder()
    assert decoder.feed(b"".join(GOOD)) == [_frame_of(m) for m in GOOD]
    assert decoder.buffered == 0


def test_fragmentation_byte_by_byte_decodes_the_same_frames():
    decoder = FrameDecoder()
    out = []
    for b in b"".join(GOOD):
        out += decoder.feed(bytes([b]))
    assert out == [_frame_of(m) for m in GOOD]


def test_header_only_frame_completes_without_further_bytes():
    decoder = FrameDecoder()
    assert decoder.feed(HEADER.pack(2, 9, 12)) == [Frame(2, 9, b"")]


def test_size_below_header_is_reported_and_only_the_12_header_bytes_skipped():
    decoder = FrameDecoder()
    bad = HEADER.pack(4, 7, 11)
    out = decoder.feed(bad + GOOD[0])
    assert out == [
        FramingError("message size 11 below the 12-byte header", 4, 7),
        _frame_of(GOOD[0]),
    ]


def test_size_zero_then_good_frame_byte_by_byte():
    decoder = FrameDecoder()
    out = []
    for b in HEADER.pack(0, 1, 0) + GOOD[2]:
        out += decoder.feed(bytes([b]))
    assert out == [
        FramingError("message size 0 below the 12-byte header", 0, 1),
        _frame_of(GOOD[2]),
    ]


def test_oversized_message_is_discarded_without_buffering_then_parsing_resumes():
    decoder = FrameDecoder()
    total = 3 * (1 << 20) + 12
    out = decoder.feed(HEADER.pack(1, 6, total))
    assert out == [FramingError(f"message size {total} above the 1 MiB bound", 1, 6)]
    assert decoder.discarding == total - 12
    # Payload that looks like headers must not be parsed.
    junk = (HEADER.pack(0, 0, 16) * ((1 << 16) // 12 + 1))[: 1 << 16]
    remaining = total - 12
    peak = 0
    while remaining:
        chunk = junk[: min(len(junk), remaining)]
        assert decoder.feed(chunk) == []
        remaining -= len(chunk)
        peak = max(peak, decoder.buffered)
        assert decoder.discarding == remaining
    assert peak == 0
    assert decoder.feed(GOOD[1]) == [_frame_of(GOOD[1])]


def test_oversized_payload_and_next_frame_in_one_chunk():
    decoder = FrameDecoder()
    size = MAX_MESSAGE_SIZE + 1
    stream = HEADER.pack(3, 8, size) + bytes(size - 12) + GOOD[3]
    out = decoder.feed(stream)
    assert out == [
        FramingError(f"message size {size} above the 1 MiB bound", 3, 8),
        _frame_of(GOOD[3]),
    ]
    assert decoder.buffered == 0 and decoder.discarding == 0


def test_a_message_of_exactly_the_bound_is_accepted_and_buffered_within_it():
    decoder = FrameDecoder()
    message = encode_request(Command.kGetRobotModel, 4, bytes(MAX_MESSAGE_SIZE - 12))
    assert decoder.feed(message[:-1]) == []
    assert decoder.buffered == MAX_MESSAGE_SIZE - 1
    out = decoder.feed(message[-1:])
    assert out == [Frame(11, 4, bytes(MAX_MESSAGE_SIZE - 12))]
    assert decoder.buffered == 0


def test_buffer_never_exceeds_one_header_plus_bounded_payload_over_3_mib():
    decoder = FrameDecoder()
    # Valid near-bound messages and oversized ones, 3+ MiB in all, fed in 100 kB chunks.
    stream = (
        encode_request(11, 1, bytes(MAX_MESSAGE_SIZE - 12))
        + HEADER.pack(1, 2, MAX_MESSAGE_SIZE + 100)
        + bytes(MAX_MESSAGE_SIZE + 88)
        + encode_request(11, 3, bytes(MAX_MESSAGE_SIZE - 12))
        + GOOD[0]
    )
    assert len(stream) > 3 * (1 << 20)
    results = []
    for i in range(0, len(stream), 100_000):
        results += decoder.feed(stream[i : i + 100_000])
        assert decoder.buffered <= MAX_MESSAGE_SIZE
    assert [type(r).__name__ for r in results] == ["Frame", "FramingError", "Frame", "Frame"]
    assert results[-1] == _frame_of(GOOD[0])


def test_custom_bound_and_header_for_other_framings():
    gripper_header = struct.Struct("<HII")  # §10.1: 10-byte header, u16 command
    decoder = FrameDecoder(max_message_size=64, header=gripper_header)
    out = decoder.feed(gripper_header.pack(1, 5, 10) + gripper_header.pack(2, 6, 65) + bytes(55))
    assert out == [Frame(1, 5, b""), FramingError("message size 65 above the 64-byte bound", 2, 6)]
    assert decoder.feed(gripper_header.pack(0, 1, 9)) == [
        FramingError("message size 9 below the 10-byte header", 0, 1)
    ]


_SMALL = 64
_EVENTS = st.lists(
    st.one_of(
        st.binary(max_size=_SMALL - 12).map(lambda p: ("good", p)),
        st.integers(0, 11).map(lambda s: ("small", s)),
        st.integers(_SMALL + 1, 4 * _SMALL).map(lambda s: ("big", s)),
    ),
    max_size=12,
)


@settings(max_examples=200)
@given(events=_EVENTS, cuts=st.lists(st.integers(0, 2000), max_size=20))
def test_any_chunking_of_good_and_bad_frames_gives_the_same_results(events, cuts):
    stream = b""
    expected: list[Frame | FramingError] = []
    for i, (kind, value) in enumerate(events):
        if kind == "good":
            stream += encode_request(7, i, value)
            expected.append(Frame(7, i, value))
        elif kind == "small":
            stream += HEADER.pack(8, i, value)
            expected.append(FramingError(f"message size {value} below the 12-byte header", 8, i))
        else:
            # The discarded payload looks like headers; none may be parsed.
            stream += HEADER.pack(9, i, value) + (HEADER.pack(0, 0, 12) * value)[: value - 12]
            expected.append(FramingError(f"message size {value} above the 64-byte bound", 9, i))
    decoder = FrameDecoder(max_message_size=_SMALL)
    bounds = sorted({c % (len(stream) + 1) for c in cuts} | {0, len(stream)})
    out = []
    for a, b in zip(bounds, bounds[1:], strict=False):
        out += decoder.feed(stream[a:b])
        assert decoder.buffered <= _SMALL
    assert out == expected
    assert decoder.buffered == 0 and decoder.discarding == 0
