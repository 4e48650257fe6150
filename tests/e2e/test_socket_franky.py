"""End to end: `franka-sim-gym serve` driven by the real franky-control 2.0.0 from PyPI.

franky's motions run libfranka's `Robot::control` loop in C++ (with its 100 Hz
command low-pass filter), unlike pylibfranka's readOnce/writeOnce. Its
constructor sends Connect, GetRobotModel x3 and SetCollisionBehavior
(docs/libfranka-client.md §0), so every scenario exercises that sequence.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.config import ControllerConfig
from tests.socket_helpers import recovery_cycles, unstarved

pytestmark = pytest.mark.socket

#: franky's constructor needs well under 1 s against the sim; libfranka has no reply
#: timeout, so an unanswered request hangs the client until this kills it.
CLIENT_TIMEOUT = 20.0

HOME = np.array([0, -math.pi / 4, 0, -3 * math.pi / 4, 0, math.pi / 2, math.pi / 4])
#: docs/fr3-model.md §6: flange pose at home.
HOME_FLANGE = np.array([0.306891, 0.0, 0.590282])
HOME_FLANGE_ROTATION = np.array(
    [[0.707107, -0.707107, 0.0], [-0.707107, -0.707107, 0.0], [0.0, 0.0, -1.0]]
)
#: docs/fr3-model.md §6 (libfranka's own model, no EE load).
HOME_GRAVITY = np.array([0.0, -1.7090, -0.6395, 18.9582, 0.7919, 1.5879, 0.0])
HOME_MASS = np.array(
    [
        [0.4985, -0.0115, 0.4333, -0.0103, 0.0270, -0.0023, 0.0004],
        [-0.0115, 1.5254, -0.0128, -0.6426, -0.0024, -0.0425, -0.0023],
        [0.4333, -0.0128, 0.9233, -0.0187, 0.0153, -0.0030, 0.0008],
        [-0.0103, -0.6426, -0.0187, 0.8340, 0.0157, 0.0873, 0.0007],
        [0.0270, -0.0024, 0.0153, 0.0157, 0.0275, 0.0020, -0.0001],
        [-0.0023, -0.0425, -0.0030, 0.0873, 0.0020, 0.0305, 0.0002],
        [0.0004, -0.0023, 0.0008, 0.0007, -0.0001, 0.0002, 0.0001],
    ]
)


def run(client, scenario: str, host: str) -> dict:
    result = client("franky", scenario, host, timeout=CLIENT_TIMEOUT)
    assert "exception" not in result, result
    return result


def test_franky_connects_and_reads_the_home_pose(serve, client):
    server = serve()
    result = run(client, "connect_state", server.host)
    state = result["state"]
    np.testing.assert_allclose(state["q"], HOME, atol=1e-3)
    np.testing.assert_allclose(result["current_joint_position"], HOME, atol=1e-3)
    T = np.asarray(state["O_T_EE"])  # franky's Affine.matrix, row-major
    np.testing.assert_allclose(T[:3, 3], HOME_FLANGE, atol=1e-3)
    np.testing.assert_allclose(T[:3, :3], HOME_FLANGE_ROTATION, atol=1e-3)
    np.testing.assert_allclose(T[3], [0, 0, 0, 1])
    assert state["robot_mode"] == "Idle"
    assert result["has_errors"] is False
    assert result["is_in_control"] is False
    log = server.log()
    assert "SetCollisionBehavior" in log  # the constructor's last request was seen
    assert "request failed" not in log


def test_joint_motion_completes_at_the_target(serve, client):
    _, result = unstarved(serve, lambda server: run(client, "joint_motion", server.host))
    assert result["error"] is None, result["error"]
    np.testing.assert_allclose(result["q_before"], HOME, atol=1e-3)
    target = np.asarray(result["target"])
    np.testing.assert_allclose(target - result["q_before"], [0.2, 0, 0, 0.2, 0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(result["q_after"], target, atol=2e-3)
    assert result["robot_mode"] == "Idle"


def test_joint_velocity_motion_moves_by_velocity_times_hold_time_and_stops(serve, client):
    _, result = unstarved(serve, lambda server: run(client, "joint_velocity_motion", server.host))
    assert result["error"] is None, result["error"]
    moved = np.asarray(result["q_after"]) - np.asarray(result["q_before"])
    expected = np.asarray(result["velocity"]) * result["hold_seconds"]  # +-0.05 on joints 4, 7
    # The ramps of franky's velocity profile at 0.2 dynamics add only a few ms of travel.
    np.testing.assert_allclose(moved, expected, atol=6e-3)
    assert moved[3] == pytest.approx(-moved[6], abs=1e-3)
    np.testing.assert_allclose(moved[[0, 1, 2, 4, 5]], 0, atol=1e-3)
    np.testing.assert_allclose(result["dq_after"], 0, atol=1e-3)  # stopped
    assert result["robot_mode"] == "Idle"


def test_model_gravity_and_mass_match_the_reference_at_home(serve, client):
    server = serve()
    result = run(client, "model", server.host)
    np.testing.assert_allclose(result["q"], HOME, atol=1e-3)
    np.testing.assert_allclose(result["gravity"], HOME_GRAVITY, atol=0.02)
    np.testing.assert_allclose(result["mass"], HOME_MASS, atol=2e-4)


def test_recover_from_errors_on_an_idle_robot_returns_promptly(serve, client):
    server = serve()
    result = run(client, "recover", server.host)
    assert result["mode_before"] == "Idle"
    assert result["returned"] is True
    # An idle arm stands still: answered after the 50 cycles of standstill, by the
    # robot's count (fci/recovery.py), not at the 0.7 s cap.
    server.stop()
    assert recovery_cycles(server.log()) == ControllerConfig().recovery_settle_cycles
    assert result["mode_after"] == "Idle"
    assert result["has_errors"] is False
