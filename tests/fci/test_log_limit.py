"""CycleLogLimit: the first warning of a kind at once, then one line with a count per
interval of cycles (the fci package reads no clock)."""

from __future__ import annotations

import logging

from franka_sim_gym.fci.log_limit import CycleLogLimit


def test_first_line_then_a_count_once_per_interval(caplog):
    limit = CycleLogLimit(logging.getLogger("test.log_limit"), interval=1000)
    with caplog.at_level(logging.WARNING, logger="test.log_limit"):
        logged = [limit.warning(cycle, "stray", "id %d", cycle) for cycle in range(2500)]
    assert [k for k, was in enumerate(logged) if was] == [0, 1000, 2000]
    assert [r.getMessage() for r in caplog.records] == [
        "id 0",
        "id 1000 (and 999 more like it in the 1000 cycles before)",
        "id 2000 (and 999 more like it in the 1000 cycles before)",
    ]


def test_kinds_are_limited_apart(caplog):
    limit = CycleLogLimit(logging.getLogger("test.log_limit"))
    with caplog.at_level(logging.WARNING, logger="test.log_limit"):
        assert limit.warning(5, ("unanswerable", 0), "robot 0")
        assert limit.warning(5, ("unanswerable", 1), "robot 1")
        assert not limit.warning(6, ("unanswerable", 0), "robot 0")
    assert len(caplog.records) == 2


def test_a_cycle_count_that_restarts_logs_again():
    limit = CycleLogLimit(logging.getLogger("test.log_limit"))
    assert limit.warning(5000, "k", "x")
    assert limit.warning(10, "k", "x")  # a count below the last line's: not suppressed
