"""End to end: the Franka Hand on port 1338, driven by pylibfranka's and franky's Gripper.

Behaviours: docs/fci-behaviour.md "Gripper fidelity"; wire format
docs/wire-protocol.md §10; statuses docs/errors.md §2.4.
"""

from __future__ import annotations

import socket
import struct
from dataclasses import dataclass

import pytest

from tests.socket_helpers import HeldClient

pytestmark = pytest.mark.socket

HEADER = struct.Struct("<HII")  # §10.1


@dataclass(frozen=True)
class Backend:
    """A finger model behind the one protocol, and how exactly its widths come out."""

    flags: tuple[str, ...]
    #: the kinematic width is exact; the physics width is measured after the servo
    #: settled (tests/e2e/test_socket_gripper_physics.py gives the tolerances)
    width_tolerance: float
    #: how far the fingers may move between the first state after stop() and 0.5 s
    #: later: kinematic none; physics braking plus what 2 cm/s covers in one 60 Hz
    #: broadcast period (0.33 mm)
    stop_tolerance: float


BACKENDS = {
    "kinematic": Backend((), 1e-6, 1e-6),
    "physics": Backend(("--gripper-physics",), 1e-4, 5e-4),
}


@pytest.fixture(params=sorted(BACKENDS))
def backend(request) -> Backend:
    """The behaviours both backends share are tested against each."""
    return BACKENDS[request.param]


def exchange(sock: socket.socket, command: int, payload: bytes = b"", size=None) -> bytes:
    """Send one gripper frame (size defaults to the true one) and return the reply bytes."""
    total = HEADER.size + len(payload) if size is None else size
    sock.sendall(HEADER.pack(command, 7, total) + payload)
    reply = sock.recv(64)
    assert len(reply) == HEADER.unpack_from(reply)[2], reply
    return reply


def in_the_commanded_time(seconds: float, expected: float) -> bool:
    """Whether a finger motion of ``expected`` s at the commanded speed took ``seconds``.

    The hand moves on the wall clock (server/gripper_server.py steps it by the time that
    passed), so a loaded machine only adds the wake-ups of the hand's timer, of the reply
    and of the client: 0.3 s at most at a load of 8 on two cores. A hand twice as slow, or
    one that jumps to the target, fails.
    """
    return 0.7 * expected < seconds < 1.3 * expected + 0.3


def test_homing_returns_true_and_opens_to_8_cm(serve, client):
    server = serve()
    result = client("gripper", "homing", server.host, timeout=30)
    assert result["ok"] is True, result
    assert result["version"] == 3
    assert result["width"] == pytest.approx(0.08)
    assert result["max_width"] == pytest.approx(0.08)
    assert result["temperature"] == 30
    assert server.stop() == 0  # Ctrl-C stops the hand beside the arm
    assert "gripper server stopped" in server.log() and "server stopped" in server.log()


def test_move_to_4_cm_takes_the_time_the_commanded_speed_implies(serve, client):
    server = serve()
    result = client("gripper", "move", server.host, timeout=30)
    assert result["ok"] is True, result
    assert result["width"] == pytest.approx(0.04, abs=1e-6)
    expected = (0.08 - 0.04) / 0.02  # 2 s
    assert in_the_commanded_time(result["seconds"], expected), result


def test_grasp_of_thin_air_returns_false_and_is_grasped_stays_false(serve, client, backend):
    server = serve(*backend.flags)
    result = client("gripper", "grasp", server.host, timeout=30)
    assert result["ok"] is False, result
    assert result["is_grasped"] is False
    assert result["width"] == pytest.approx(0.0, abs=backend.width_tolerance)


def test_grasp_of_zero_on_nothing_succeeds(serve, client, backend):
    server = serve(*backend.flags)
    result = client("gripper", "grasp_zero", server.host, timeout=30)
    assert result["ok"] is True and result["is_grasped"] is True, result


def test_grasp_closes_on_the_configured_object_and_sets_is_grasped(serve, client):
    server = serve("--gripper-object-width", "0.04")
    result = client("gripper", "grasp", server.host, timeout=30)
    assert result["ok"] is True, result
    assert result["is_grasped"] is True
    assert result["width"] == pytest.approx(0.04, abs=1e-6)
    assert in_the_commanded_time(result["seconds"], 0.8), result  # 4 cm closed at 5 cm/s


def test_object_width_flag_wins_over_the_environment(serve, client):
    server = serve(
        "--gripper-object-width", "0.04", env={"FRANKA_SIM_GRIPPER_OBJECT_WIDTH": "0.02"}
    )
    assert client("gripper", "grasp", server.host, timeout=30)["ok"] is True
    server = serve(env={"FRANKA_SIM_GRIPPER_OBJECT_WIDTH": "0.04"})
    assert client("gripper", "grasp", server.host, timeout=30)["ok"] is True


def test_out_of_stroke_width_raises_command_failed(serve, client, backend):
    server = serve(*backend.flags)
    result = client("gripper", "out_of_stroke", server.host, timeout=30)
    assert result["errors"] == ["CommandException: libfranka gripper: Command failed!"] * 2
    assert result["homing_after"] is True  # the connection keeps working
    assert "invalid-argument" in server.log()


def test_stop_mid_move_halts_in_place(serve, client, backend):
    server = serve(*backend.flags)
    result = client("franky_gripper", "stop_mid_move", server.host, timeout=30)
    assert result["stop"] is True, result
    assert result["move"] == "CommandException: libfranka gripper: Command aborted!"
    # 0.3 s at 2 cm/s from 8 cm: about 7.4 cm, and not reopened afterwards.
    assert 0.0 < result["width"] < result["start_width"] - 0.002
    assert result["width"] == pytest.approx(0.074, abs=0.004)
    assert result["width"] == pytest.approx(result["width_at_stop"], abs=backend.stop_tolerance)


def test_franky_gripper_homing_and_move_work(serve, client):
    server = serve()
    result = client("franky_gripper", "homing_move", server.host, timeout=30)
    assert result["homing"] is True and result["move"] is True, result
    assert result["width_after_homing"] == pytest.approx(0.08)
    assert in_the_commanded_time(result["move_seconds"], 0.8), result  # 4 cm at 5 cm/s
    assert result["opened"] is True and result["width"] == pytest.approx(0.08)


def test_franky_gripper_grasps_the_object_and_fails_on_thin_air(serve, client):
    server = serve()
    empty = client("franky_gripper", "grasp", server.host, timeout=30)
    assert empty["ok"] is False and empty["is_grasped"] is False, empty
    server = serve("--gripper-object-width", "0.04")
    held = client("franky_gripper", "grasp", server.host, timeout=30)
    assert held["ok"] is True and held["is_grasped"] is True, held
    assert held["width"] == pytest.approx(0.04, abs=1e-6)


def test_franky_gripper_out_of_stroke_width_raises(serve, client):
    server = serve()
    result = client("franky_gripper", "out_of_stroke", server.host, timeout=30)
    assert result["error"] == "CommandException: libfranka gripper: Command failed!", result
    assert result["homing_after"] is True
    assert "invalid-argument" in server.log()


def test_second_gripper_client_is_refused_while_the_first_keeps_working(serve, client):
    server = serve()
    first = HeldClient("gripper", "hold", server.host)
    second = client("gripper", "connect_only", server.host, timeout=30)
    held = first.release()
    assert second["error"] is not None, second
    assert "a gripper client is already connected" in server.log()
    # The first client's 60 Hz stream ran on through the refusal (the hand's message ids)
    # and its connection still moves the fingers.
    assert "exception" not in held, held
    ids = [held["told_id"], *held["after_ids"]]
    assert ids == sorted(set(ids)), ids  # strictly increasing
    assert held["move_after"] is True


def test_connect_with_another_version_is_answered_incompatible_with_version_3(serve):
    server = serve()
    with socket.create_connection((server.host, 1338), timeout=5) as sock:
        reply = exchange(sock, 0, struct.pack("<HH", 2, 5555))
    assert reply == HEADER.pack(0, 7, 14) + struct.pack("<HH", 1, 3)


def test_bad_requests_are_answered_and_logged_with_a_reason(serve):
    server = serve()
    fail = HEADER.pack(9, 7, 12) + struct.pack("<H", 1)
    with socket.create_connection((server.host, 1338), timeout=5) as sock:
        assert exchange(sock, 9) == fail  # unknown command id
        # A Connect of 16 bytes: answered like a bad Connect (status 1, version 3).
        wrong = exchange(sock, 0, struct.pack("<HHH", 3, 5555, 0))
        assert wrong == HEADER.pack(0, 7, 14) + struct.pack("<HH", 1, 3)
        # A declared size below the 10-byte header.
        assert exchange(sock, 1, size=4) == HEADER.pack(1, 7, 12) + struct.pack("<H", 1)
        # Homing before Connect.
        assert exchange(sock, 1) == HEADER.pack(1, 7, 12) + struct.pack("<H", 1)
        # After a good Connect, a non-finite Move width is kFail.
        assert exchange(sock, 0, struct.pack("<HH", 3, 5555)) == HEADER.pack(
            0, 7, 14
        ) + struct.pack("<HH", 0, 3)
        nan_move = exchange(sock, 3, struct.pack("<dd", float("nan"), 0.1))
        assert nan_move == HEADER.pack(3, 7, 12) + struct.pack("<H", 1)
    log = server.log()
    for reason in ("unknown-command", "wrong-size", "bad-frame", "before-connect"):
        assert reason in log, reason
    assert "invalid-argument" in log


def test_no_gripper_serves_the_arm_alone(serve):
    server = serve("--no-gripper")
    with pytest.raises(OSError):
        socket.create_connection((server.host, 1338), timeout=1).close()
