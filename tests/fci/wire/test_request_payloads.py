"""The request payloads of v10 (fci/wire/request_payloads.py, docs/wire-protocol.md §3-§6): sizes,
round trips, byte positions, errors."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci.wire.protocol import (
    HEADER,
    Command,
    encode_connect_request,
    encode_message,
    encode_move_request,
)
from franka_sim_gym.fci.wire.request_payloads import (
    REQUEST_SIZE,
    AutomaticErrorRecoveryRequest,
    ConnectRequest,
    GetRobotModelRequest,
    MoveRequest,
    ProtocolError,
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
