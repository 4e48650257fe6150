"""franka_ros2's hardware interface, replayed: the libfranka calls franka_hardware makes
(tests/e2e/clients/franka_hardware_client.py, read from franka_ros2's
franka_hardware/src/robot.cpp and franka_hardware_interface.cpp) sent by pylibfranka,
the same libfranka 0.21 underneath. franka_ros2 itself (ROS 2, ros2_control) is not
installed here: this is its call sequence, not the program (docs/real-clients.md)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.socket_helpers import motion_summaries

pytestmark = pytest.mark.socket

#: docs/fr3-model.md §6: libfranka's gravity at the home pose, no load.
HOME_GRAVITY = np.array([0.0, -1.7090, -0.6395, 18.9582, 0.7919, 1.5879, 0.0])


def test_franka_hardwares_libfranka_sequence_runs_against_serve(serve, client):
    # In lockstep, so that a loaded machine's lost cycles are not the robot's.
    flags = ("--lockstep", "--enforce-motion-limits", "--enforce-comm-constraints", "--no-gripper")
    server = serve(*flags)
    r = client("franka_hardware", "replay", server.host, timeout=120)
    server.stop()
    assert "exception" not in r, r
    # The model loaded on connect: gravity at the home pose (franka::Model, as libfranka's).
    np.testing.assert_allclose(r["gravity_at_start"], HOME_GRAVITY, atol=0.02)
    # Setters accepted, torque control started at once, 1 s of the impedance controller.
    assert r["torque"]["cycles"] == 1000 and r["torque"]["recovered_to_start"] is False
    # The bad command ends the torque control with the robot's own reflex ...
    assert r["reflex"] is not None and '["controller_torque_discontinuity"]' in r["reflex"]
    assert r["mode_after_reflex"] == "Reflex"
    # ... and the error-recovery action makes the next start succeed.
    assert r["mode_recovered"] == "Idle"
    assert r["again"]["cycles"] == 300 and r["again"]["recovered_to_start"] is False
    assert r["mode_end"] == "Idle"
    log = server.log()
    assert "rejected" not in log, log[-3000:]
    # Each controller switch drops the running control (StopMove: kPreempted), none
    # loses a cycle; the bad command is the one reflex.
    assert motion_summaries(log) == [
        ("kPreempted", 0, 0),
        ("kPreempted", 0, 0),
        ("kReflexAborted", 0, 0),
        ("kPreempted", 0, 0),
    ]
