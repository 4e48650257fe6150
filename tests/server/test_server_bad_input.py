"""Bad input reaches the server: it logs a named reason, answers as the robot would, and keeps
serving the connected client."""

from __future__ import annotations

import socket
import struct
import time

import numpy as np
import pytest

from franka_sim_gym.fci.wire import MotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire import protocol as p
from tests.raw_client import RawClient

pytestmark = pytest.mark.socket


@pytest.fixture
def raw(serve):
    server = serve()
    client = RawClient(server.host)
    status, version = client.connect()
    assert (status, version) == (p.ConnectStatus.kSuccess, p.VERSION)
    client.state()
    yield server, client
    client.close()


def still_serving(client: RawClient) -> None:
    """States keep coming and a request is still answered."""
    before = int(client.latest_state()["message_id"])
    time.sleep(0.05)
    assert int(client.latest_state()["message_id"]) > before
    reply = client.reply(client.request(p.Command.kGetRobotModel))
    assert reply.payload[0] == p.GetterStatus.kSuccess
    assert b"<robot" in reply.payload


def wait_for_log(server, text: str, timeout: float = 3.0) -> None:
    deadline = time.monotonic() + timeout
    while text not in server.log():
        if time.monotonic() > deadline:
            raise AssertionError(f"{text!r} not in the server log:\n{server.log()}")
        time.sleep(0.05)


def test_frame_below_the_header_size_is_logged_and_skipped(raw):
    server, client = raw
    client.send_raw(p.HEADER.pack(p.Command.kStopMove, 99, 8))
    wait_for_log(server, "message size 8 below the 12-byte header")
    still_serving(client)


def test_frame_above_one_mebibyte_is_discarded_without_buffering(raw):
    server, client = raw
    size = 2 * 1024 * 1024
    client.send_raw(p.HEADER.pack(p.Command.kSetLoad, 98, size))
    client.send_raw(b"\0" * (size - 12))
    wait_for_log(server, f"message size {size} above the 1 MiB bound")
    still_serving(client)


def test_unknown_command_id_is_answered_and_logged(raw):
    server, client = raw
    command_id = client.request(42)
    reply = client.reply(command_id)
    assert reply.command_id == command_id
    assert reply.payload[0] == 1  # kCommandNotPossibleRejected: the robot cannot do it
    wait_for_log(server, "unknown command id 42")
    still_serving(client)


def test_truncated_payload_is_answered_invalid_argument(raw):
    server, client = raw
    command_id = client.request(p.Command.kSetLoad, b"\0" * 40)
    assert client.reply(command_id).payload[0] == p.SetterStatus.kInvalidArgumentRejected
    wait_for_log(server, "truncated SetLoad payload")
    command_id = client.request(p.Command.kMove, b"\0" * 10)
    assert client.reply(command_id).payload[0] == p.MoveStatus.kInvalidArgumentRejected
    still_serving(client)


def test_udp_datagram_of_the_wrong_size_is_ignored(raw):
    server, client = raw
    client.latest_state()
    client.udp.sendto(b"\0" * 100, client.server_udp)
    wait_for_log(server, "ignored a 100-byte datagram")
    assert "a RobotCommand is 371 bytes" in server.log()
    still_serving(client)


def test_udp_commands_from_another_address_are_ignored(raw):
    server, client = raw
    client.latest_state()
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    stranger.bind((client.host, 0))
    stranger.sendto(b"\0" * 371, client.server_udp)
    stranger.close()
    wait_for_log(server, "ignored a 371-byte datagram from")
    still_serving(client)


def test_nan_in_a_command_is_refused_and_the_motion_goes_on(raw):
    server, client = raw
    move = client.request(
        p.Command.kMove,
        p.MoveRequest(0, 0, p.DEFAULT_DEVIATION, p.DEFAULT_DEVIATION, False, (0.0,) * 7).payload(),
    )
    assert client.reply(move).payload[0] == p.MoveStatus.kMotionStarted
    state = client.latest_state()
    while state["motion_generator_mode"] != MotionGeneratorMode.kJointPosition:
        state = client.state()
    q = state["q_d"].astype(float)
    bad = q.copy()
    bad[1] = np.nan
    client.send_command(message_id=int(state["message_id"]), q_c=bad)
    wait_for_log(server, "non-finite value in the commanded q_c")
    state = client.latest_state()
    assert np.all(np.isfinite(state["q_d"])) and np.all(np.isfinite(state["q"]))
    assert state["robot_mode"] == RobotMode.kMove
    for _ in range(50):  # finish like libfranka: repeat the final command until idle
        state = client.latest_state()
        client.send_command(
            message_id=int(state["message_id"]), q_c=q, motion_generation_finished=True
        )
        if state["motion_generator_mode"] == MotionGeneratorMode.kIdle:
            break
    assert client.reply(move).payload[0] == p.MoveStatus.kSuccess
    still_serving(client)


def test_request_before_connect_is_rejected(serve):
    server = serve()
    client = RawClient(server.host)
    command_id = client.request(p.Command.kStopMove)
    assert client.reply(command_id).payload[0] == p.StopMoveStatus.kCommandNotPossibleRejected
    wait_for_log(server, "StopMove before Connect")
    client.close()


def test_connect_with_another_library_version_is_incompatible(serve):
    server = serve()
    client = RawClient(server.host)
    assert client.connect(version=9) == (p.ConnectStatus.kIncompatibleLibraryVersion, 10)
    wait_for_log(server, "library version 9 is not 10")
    client.close()


def test_reply_header_echoes_the_request(raw):
    _, client = raw
    command_id = client.request(p.Command.kSetGuidingMode, struct.pack("<7?", *([True] * 7)))
    reply = client.reply(command_id)
    assert reply.command == p.Command.kSetGuidingMode
    assert reply.payload[0] == p.SetterStatus.kSuccess
