"""Socket mode with pylibfranka against `serve --enforce-comm-constraints`: the 20-cycle bound
is counted in cycles the robot published and nobody answered."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.socket


def test_a_client_silent_for_30_ms_gets_communication_constraints_violation(serve, client):
    server = serve("--enforce-comm-constraints")
    r = client("pylibfranka", "silence", server.host, env={"SILENCE_MS": "30"}, timeout=60)
    assert "exception" not in r, r
    assert r["error"] is not None and '["communication_constraints_violation"]' in r["error"]
    assert r["mode_after"] == "Reflex"
    assert r["next_motion_final_mode"] == "Idle"  # after recovery the next motion runs


def test_a_client_silent_for_10_ms_is_not_aborted(serve, client):
    server = serve("--enforce-comm-constraints")
    r = client("pylibfranka", "silence", server.host, env={"SILENCE_MS": "10"}, timeout=60)
    assert "exception" not in r, r
    assert r["error"] is None
    assert r["mode_after"] == "Idle"
    assert "communication_constraints_violation" not in server.log()
