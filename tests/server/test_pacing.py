"""The server's 1 kHz schedule (server/pacing.py): a late state keeps its answer window,
the schedule catches up over the next cycles, and a hopeless lag restarts the clock."""

from __future__ import annotations

import pytest

from franka_sim_gym.server.pacing import CYCLE_S, MAX_LAG_S, MIN_ANSWER_WINDOW_S, next_tick


def test_a_tick_on_time_wakes_at_the_next_millisecond():
    wake, slot = next_tick(10.0, 10.0 + 50e-6)
    assert slot == pytest.approx(10.001)
    assert wake == slot


def test_a_late_state_keeps_the_minimum_answer_window():
    # The tick of slot 10.000 sent its state 0.9 ms late: the next cycle is not run
    # 0.1 ms later (that cycle would be lost to a client that did nothing wrong).
    sent = 10.0009
    wake, slot = next_tick(10.0, sent)
    assert wake == pytest.approx(sent + MIN_ANSWER_WINDOW_S)
    assert slot == pytest.approx(10.001)  # the schedule itself does not slip


def run(ticks: int, hiccup_at: int, hiccup_s: float, tick_s: float = 40e-6) -> list[float]:
    """The send times of ``ticks`` ticks, one of them held up ``hiccup_s`` (the host
    did not schedule the thread), each taking ``tick_s``."""
    sent, now, slot = [], 0.0, 0.0
    for k in range(ticks):
        now += tick_s + (hiccup_s if k == hiccup_at else 0.0)
        sent.append(now)
        wake, slot = next_tick(slot, now)
        now = max(now, wake)
    return sent


def test_after_a_hiccup_every_state_gets_its_window_and_the_rate_catches_up():
    sent = run(100, hiccup_at=10, hiccup_s=0.003)
    gaps = [b - a for a, b in zip(sent[:-1], sent[1:], strict=True)]
    assert min(gaps) >= MIN_ANSWER_WINDOW_S
    # No burst: the 3 ms are made up at 0.4 ms a cycle, then the schedule holds.
    assert max(gaps[20:]) == pytest.approx(CYCLE_S)
    assert sent[-1] == pytest.approx(99 * CYCLE_S + 40e-6, abs=1e-9)


def test_a_lag_beyond_the_bound_restarts_the_clock():
    late = 10.0 + CYCLE_S + MAX_LAG_S + 1e-3
    wake, slot = next_tick(10.0, late)
    assert slot == pytest.approx(late + CYCLE_S)
    assert wake == slot
