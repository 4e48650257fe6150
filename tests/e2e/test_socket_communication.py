"""Socket mode with pylibfranka against `serve --enforce-comm-constraints`: the 20-cycle bound
is counted in cycles the robot published and nobody answered."""

from __future__ import annotations

import pytest

from tests.socket_helpers import motion_summaries

pytestmark = pytest.mark.socket


def test_a_client_silent_for_100_ms_gets_communication_constraints_violation(serve, client):
    """100 ms of silence is 100 cycles at 1 kHz: a loaded server that runs only a few
    hundred cycles a second still publishes the 20 unanswered states the bound counts."""
    server = serve("--enforce-comm-constraints")
    r = client("pylibfranka_reflex", "silence", server.host, env={"SILENCE_MS": "100"}, timeout=60)
    assert "exception" not in r, r
    assert r["error"] is not None and '["communication_constraints_violation"]' in r["error"]
    assert r["mode_after"] == "Reflex"
    assert r["next_motion_final_mode"] == "Idle"  # after recovery the next motion runs
    server.stop()
    # The 20th lost cycle aborts (the bound is counted in cycles), the next motion is clean.
    (status, _, longest), (next_status, *_) = motion_summaries(server.log())
    assert (status, longest, next_status) == ("kReflexAborted", 20, "kSuccess")


def test_a_client_silent_for_12_cycles_is_not_aborted(serve, client):
    """Fewer than 20 consecutive lost cycles are extrapolated, never aborted.

    The silence is counted in the robot's cycles: the client reads the states (their
    message ids) and answers none until 12 have passed, so a loaded server's slower clock
    does not shorten it (10 ms of wall time was 3 cycles at a load of 12). A loaded
    machine can still stall the client past that; an attempt whose run reached 20 proves
    nothing and is repeated.
    """
    for _attempt in range(3):
        server = serve("--enforce-comm-constraints")
        r = client(
            "pylibfranka_reflex", "silence", server.host, env={"SILENCE_CYCLES": "12"}, timeout=60
        )
        assert "exception" not in r, r
        server.stop()
        summaries = motion_summaries(server.log())
        assert len(summaries) == 2, server.log()  # the silent motion, then the next one
        status, lost, longest = summaries[0]
        if longest >= 20:  # the machine stalled the client past the bound: inconclusive
            assert status == "kReflexAborted" and r["error"] is not None
            continue
        assert longest >= 12, summaries  # the silence went unanswered
        assert status == "kSuccess", summaries
        assert r["error"] is None
        assert r["mode_after"] == "Idle"
        assert "communication_constraints_violation" not in server.log()
        return
    pytest.fail(f"every attempt's client stalled past 20 cycles ({summaries}): too loaded")
