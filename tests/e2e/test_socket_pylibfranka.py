"""End to end: `franka-sim-gym serve` driven by the real pylibfranka 0.21.3 from PyPI."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from tests.socket_helpers import HeldClient, unstarved

pytestmark = pytest.mark.socket

HOME = np.array([0, -math.pi / 4, 0, -3 * math.pi / 4, 0, math.pi / 2, math.pi / 4])
HOME_FLANGE = np.array([0.306891, 0.0, 0.590282])
#: docs/fr3-model.md §6 (libfranka's own model, no EE load).
HOME_GRAVITY = np.array([0.0, -1.7090, -0.6395, 18.9582, 0.7919, 1.5879, 0.0])
HOME_MASS_DIAGONAL = np.array([0.4985, 1.5254, 0.9233, 0.8340, 0.0275, 0.0305, 0.0001])


def column_major(values) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(4, 4).T


def fk_flange(q: np.ndarray) -> np.ndarray:
    """Forward kinematics from docs/fr3-model.md §2.1 (modified DH), independent of the sim."""
    dh = [
        (0, 0.333, 0),
        (0, 0, -math.pi / 2),
        (0, 0.316, math.pi / 2),
        (0.0825, 0, math.pi / 2),
        (-0.0825, 0.384, -math.pi / 2),
        (0, 0, math.pi / 2),
        (0.088, 0, math.pi / 2),
    ]
    T = np.eye(4)
    for (a, d, alpha), theta in zip(dh, q, strict=True):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        T = T @ np.array(
            [
                [ct, -st, 0, a],
                [st * ca, ct * ca, -sa, -d * sa],
                [st * sa, ct * sa, ca, d * ca],
                [0, 0, 0, 1],
            ]
        )
    flange = np.eye(4)
    flange[2, 3] = 0.107
    return T @ flange


def test_connect_and_read_once_at_home(serve, client):
    server = serve()
    result = client("pylibfranka", "read_once", server.host)
    assert "exception" not in result, result
    first, second = result["first"], result["second"]
    np.testing.assert_allclose(first["q"], HOME, atol=1e-4)
    T = column_major(first["O_T_EE"])
    np.testing.assert_allclose(T[3], [0, 0, 0, 1])
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5)
    np.testing.assert_allclose(T, fk_flange(np.array(first["q"])), atol=1e-4)
    np.testing.assert_allclose(T[:3, 3], HOME_FLANGE, atol=1e-4)
    assert first["robot_mode"] == "Idle"
    np.testing.assert_allclose(first["O_ddP_O"], [0, 0, -9.81], atol=1e-6)
    assert second["time"] > first["time"]  # message ids strictly increase


def test_load_model_gravity_and_mass_match_the_reference(serve, client):
    server = serve()
    result = client("pylibfranka", "load_model", server.host)
    assert "exception" not in result, result
    np.testing.assert_allclose(result["gravity"], HOME_GRAVITY, atol=0.02, rtol=0.01)
    mass = np.asarray(result["mass"]).reshape(7, 7)
    np.testing.assert_allclose(np.diag(mass), HOME_MASS_DIAGONAL, atol=2e-3, rtol=0.01)


def test_cosine_joint_position_motion_succeeds_and_tracks(serve, client):
    _, result = unstarved(serve, lambda server: client("pylibfranka", "cosine_motion", server.host))
    assert "exception" not in result, result
    assert result["max_tracking_error"] < 1e-2
    final = result["final"]
    assert final["robot_mode"] == "Idle"
    np.testing.assert_allclose(final["q"], result["q_start"], atol=2e-3)
    assert final["success_rate"] == 0.0  # no motion running


def test_joint_velocity_motion_succeeds(serve, client):
    _, result = unstarved(
        serve, lambda server: client("pylibfranka", "joint_velocity", server.host)
    )
    assert "exception" not in result, result
    moved = np.asarray(result["q_after"]) - np.asarray(result["q_before"])
    assert moved[3] == pytest.approx(result["expected_displacement"], abs=0.02)
    assert moved[6] == pytest.approx(-result["expected_displacement"], abs=0.02)
    assert result["robot_mode"] == "Idle"


def test_torque_motion_of_zero_torque_holds_within_a_milliradian(serve, client):
    server = serve()
    result = client("pylibfranka", "torque_zero_hold", server.host)
    assert "exception" not in result, result
    assert result["max_deviation"] < 1e-3
    # tau_J is the measured torque: gravity is in it even at zero commanded torque
    assert result["tau_J"][3] == pytest.approx(HOME_GRAVITY[3], rel=0.05)
    assert result["final_mode"] == "Idle"


def test_stop_move_from_another_thread_preempts(serve, client):
    server = serve()
    result = client("pylibfranka", "stop_from_thread", server.host)
    assert "exception" not in result, result
    assert result["error"] is not None and "Move command preempted" in result["error"]
    assert result["stopper_error"] == []
    assert result["mode"] == "Idle"


def test_disconnect_mid_motion_then_reconnect_and_move(serve, client):
    server = serve()
    vanished = client("pylibfranka", "vanish_mid_motion", server.host)
    assert vanished == {"vanished_after_cycles": 200}
    time.sleep(0.3)
    result = client("pylibfranka", "reconnect_and_move", server.host)
    assert "exception" not in result, result
    assert result["mode_on_connect"] == "Idle"
    assert result["final"]["robot_mode"] == "Idle"
    assert server.alive()
    assert server.log().count("disconnected") >= 2  # the readiness probe and the client


def test_second_client_is_refused_while_the_first_keeps_running(serve, client):
    server = serve()
    first = HeldClient("pylibfranka", "hold_connection", server.host)
    second = client("pylibfranka", "connect_only", server.host, timeout=30)
    held = first.release()
    assert second["error"] is not None, second
    assert "a client is already connected" in server.log()
    # The first client kept its stream through the refusal and after it: 100 more
    # states, each a later cycle of the robot (its message ids).
    assert "exception" not in held, held
    ids = [held["told_id"], *held["after_ids"]]
    assert ids == sorted(set(ids)), ids  # strictly increasing
    assert held["first_id"] <= held["told_id"]


def test_ctrl_c_exits_cleanly(serve):
    server = serve()
    assert server.stop() == 0
    assert "server stopped" in server.log()
