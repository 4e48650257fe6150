"""The drawn links of a reality profile (envs/channel.py DrawnLinks, docs/reality.md "The
link"): which datagrams reach the robot in their cycle."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.envs.channel import DrawnLinks, Links


def links_with(loss, jitter, cycles, u):
    """Two arms' links whose draws for the next cycles are ``u`` (cycles, 2, 2): per cycle
    and arm, the loss's and the spike's uniform."""
    links = DrawnLinks(2)
    links.loss[:], links.jitter[:], links.cycles[:] = loss, jitter, cycles
    links.ahead.take = lambda count: u[:count]
    links.begin_step(len(u))
    return links


def delivered(links, cycles):
    sending = np.ones(2, dtype=bool)
    return np.array([links.transmit(sending) for _ in range(cycles)])


def test_a_spike_of_d_cycles_holds_up_d_datagrams_and_the_next_arrives():
    u = np.full((6, 2, 2), 0.9)
    u[1, 0, 1] = 0.45  # arm 0, cycle 1: u / jitter = 0.9 of 3 cycles -> a spike of 3
    links = links_with([0.0, 0.0], [0.5, 0.5], [3, 3], u)
    got = delivered(links, 6)
    np.testing.assert_array_equal(got[:, 0], [True, False, False, False, True, True])
    assert got[:, 1].all()  # the other arm's link is its own


def test_spikes_overlap_to_the_later_end_and_a_loss_is_one_cycle():
    u = np.full((7, 2, 2), 0.9)
    u[0, 0, 1] = 0.45  # a spike of 1 + int(0.9 * 3) = 3 cycles (0, 1, 2)
    u[1, 0, 1] = 0.1  # and one of 1 + int(0.2 * 3) = 1 inside it: still held to cycle 3
    u[5, 1, 0] = 0.0  # arm 1 loses cycle 5's datagram
    links = links_with([0.01, 0.01], [0.5, 0.5], [3, 3], u)
    got = delivered(links, 7)
    np.testing.assert_array_equal(got[:, 0], [False, False, False, True, True, True, True])
    np.testing.assert_array_equal(got[:, 1], [True, True, True, True, True, False, True])


def test_a_perfect_draw_hands_over_the_sending_mask_itself():
    links = links_with([0.0, 0.0], [0.0, 0.0], [3, 3], np.full((2, 2, 2), 0.5))
    sending = np.array([True, False])
    assert links.transmit(sending) is sending


def test_a_spike_at_the_end_of_a_step_holds_up_the_next_steps_first_datagrams():
    u = np.full((3, 2, 2), 0.9)
    u[2, 0, 1] = 0.45  # arm 0, the step's last cycle: a spike of 3 (cycles 2, 3, 4)
    links = links_with([0.0, 0.0], [0.5, 0.5], [3, 3], u)
    first = delivered(links, 3)
    links.ahead.take = lambda count: np.full((count, 2, 2), 0.9)  # a quiet next step
    links.begin_step(4)
    second = delivered(links, 4)
    np.testing.assert_array_equal(first[:, 0], [True, True, False])
    np.testing.assert_array_equal(second[:, 0], [False, False, True, True])
    assert first[:, 1].all() and second[:, 1].all()


def test_the_links_count_a_sending_arms_lost_runs_and_the_robots_own_answers():
    links = Links(None, 3)
    links.robot_answers[2] = True  # the asynchronous generator answers its cycles itself
    lost = np.zeros(3, dtype=np.int64)
    sending = np.array([True, False, True])
    nothing = np.zeros(3, dtype=bool)
    for _ in range(3):
        links._account(sending, nothing, lost)
    assert links._in_run
    np.testing.assert_array_equal(lost, [3, 0, 0])
    np.testing.assert_array_equal(links.lost_run, [3, 0, 0])
    links._account(np.array([False, True, True]), nothing, lost)  # arm 0 pauses, arm 1 lost
    np.testing.assert_array_equal(links.lost_run, [3, 1, 0])
    links._account(np.ones(3, dtype=bool), np.array([True, True, False]), lost)
    np.testing.assert_array_equal(links.lost_run, [0, 0, 0])
    np.testing.assert_array_equal(links.longest_lost, [3, 1, 0])
    np.testing.assert_array_equal(lost, [3, 1, 0])
    assert not links._in_run
    with pytest.raises(ValueError, match="answered"):
        links._account(sending, np.zeros(2, dtype=bool), lost)
