"""End to end: pylibfranka's AsyncPositionControlHandler (libfranka's asynchronous joint-position
control) against `franka-sim-gym serve --enforce-motion-limits --enforce-comm-constraints`:
the robot's own generator moves q_d to the client's sparse targets (docs/motion-limits.md
"The asynchronous generator")."""

from __future__ import annotations

import numpy as np
import pytest

from tests.socket_helpers import motion_summaries

pytestmark = pytest.mark.socket

ENFORCING = ("--enforce-motion-limits", "--enforce-comm-constraints")


def test_targets_at_50_hz_are_reached_then_stop_control_ends_the_motion_at_rest(serve, client):
    server = serve(*ENFORCING)
    r = client("async", "sequence", server.host, timeout=90)
    server.stop()
    assert "exception" not in r, r
    assert r["status_before_target"] == "kIdle"
    for leg in r["legs"]:
        assert leg["errors"] == [], leg
        assert "kAborted" not in leg["statuses"], leg
        # Each 0.3 rad leg at the caps (0.655 / 1.315 rad/s) is reached, and stays reached
        # (~0.55 s of the robot's time; the client waits up to 10 s of a loaded machine's).
        assert leg["last_status"] == "kTargetReached", leg
        assert leg["reached_after"] is not None and leg["reached_after"] > 0.2, leg
    # stop_control's all-zero target is not a target: the arm stops where it was sent.
    np.testing.assert_allclose(r["q_d_after_stop"], r["legs"][-1]["goal"], atol=2e-3)
    assert max(abs(v) for v in r["dq_d_after_stop"]) == 0.0
    assert r["mode_after_stop"] == "Idle" and r["last_motion_errors"] == "[]"
    assert r["status_after_stop"] == "kAborted"  # the handler's own state after stop_control
    assert r["second_mode"] == "Idle" and r["second_errors"] == "[]"
    log = server.log()
    assert "motion limit violated" not in log
    assert [s for s, *_ in motion_summaries(log)] == ["kSuccess", "kSuccess"]
    assert all(lost == 0 for _, lost, _ in motion_summaries(log))


def test_a_target_outside_the_joint_range_aborts_with_12(serve, client):
    server = serve(*ENFORCING)
    r = client("async", "out_of_range", server.host, timeout=60)
    server.stop()
    assert "exception" not in r, r
    assert r["status"] == "kAborted"
    assert "motion aborted by reflex" in r["feedback_error"]
    assert '["joint_motion_generator_position_limits_violation"]' in r["feedback_error"]
    assert r["mode"] == "Reflex"
    assert r["last_motion_errors"] == '["joint_motion_generator_position_limits_violation"]'
    assert abs(r["q4"] - r["start_q4"]) < 1e-3  # the arm never headed for the target
    assert [s for s, *_ in motion_summaries(server.log())] == ["kReflexAborted"]


def test_half_a_second_without_a_datagram_is_no_communication_violation(serve, client):
    server = serve(*ENFORCING)
    r = client("async", "sparse_targets", server.host, timeout=60)
    server.stop()
    assert "exception" not in r, r
    assert r["status"] == "kTargetReached", r
    assert r["final_mode"] == "Idle" and r["final_errors"] == "[]"
    assert r["distance"] < 1e-3
    assert "communication_constraints_violation" not in server.log()
