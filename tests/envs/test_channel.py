"""The drawn links of a reality profile (envs/channel.py DrawnLinks, docs/reality.md "The
link"): which datagrams reach the robot in their cycle."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.envs.channel import Links
from franka_sim_gym.reality import DrawBatch, draw, load_profile


def links_with(loss, jitter, cycles, u):
    """Two arms' drawn links whose draws for the next cycles are ``u`` (cycles, 2, 2): per
    cycle and arm, the loss's and the spike's uniform."""
    links = Links(None, 2, drawn=True)
    drawn = links.drawn
    drawn.loss[:], drawn.jitter[:], drawn.cycles[:] = loss, jitter, cycles
    drawn.ahead.take = lambda count: u[:count]
    links.begin_step(len(u))
    return links


def quiet_draws(count):
    """Draws of ``count`` cycles in which nothing is lost or held up."""
    return np.full((count, 2, 2), 0.9)


def delivered(links, cycles, lost=None):
    """Per cycle, the arms whose datagram the links handed to the robot (both sending)."""
    sending = np.ones(2, dtype=bool)
    lost = np.zeros(2, dtype=np.int64) if lost is None else lost
    got = []
    for _ in range(cycles):
        links.transmit(None, sending, lost, lambda command, mask: got.append(mask.copy()))
    return np.array(got)


def test_a_spike_of_d_cycles_holds_up_d_datagrams_and_the_next_arrives():
    u = np.full((6, 2, 2), 0.9)
    u[1, 0, 1] = 0.45  # arm 0, cycle 1: u / jitter = 0.9 of 3 cycles -> a spike of 3
    links = links_with([0.0, 0.0], [0.5, 0.5], [3, 3], u)
    lost = np.zeros(2, dtype=np.int64)
    got = delivered(links, 6, lost)
    np.testing.assert_array_equal(got[:, 0], [True, False, False, False, True, True])
    assert got[:, 1].all()  # the other arm's link is its own
    np.testing.assert_array_equal(lost, [3, 0])  # each held-up cycle is a lost one
    np.testing.assert_array_equal(links.longest_lost, [3, 0])
    np.testing.assert_array_equal(links.lost_run, [0, 0])  # closed by the next arrival


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
    got = []
    links.transmit(None, sending, np.zeros(2, dtype=np.int64), lambda c, m: got.append(m))
    assert got[0] is sending


def test_a_spike_at_the_end_of_a_step_holds_up_the_next_steps_first_datagrams():
    u = np.full((3, 2, 2), 0.9)
    u[2, 0, 1] = 0.45  # arm 0, the step's last cycle: a spike of 3 (cycles 2, 3, 4)
    links = links_with([0.0, 0.0], [0.5, 0.5], [3, 3], u)
    first = delivered(links, 3)
    links.drawn.ahead.take = quiet_draws
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


def test_a_step_that_ends_early_leaves_the_clock_at_its_last_transmitted_cycle():
    u = np.full((3, 2, 2), 0.9)
    u[1, 0, 1] = 0.45  # arm 0, cycle 1: a spike of 3 (cycles 1, 2, 3)
    u[2, 1, 1] = 0.45  # arm 1, cycle 2: a spike of a datagram never sent
    links = links_with([0.0, 0.0], [0.5, 0.5], [3, 3], u)
    first = delivered(links, 2)  # the step ends after two of its three cycles
    links.drawn.ahead.take = quiet_draws
    links.begin_step(3)
    second = delivered(links, 3)  # cycles 2, 3, 4 of the links' clock
    np.testing.assert_array_equal(first[:, 0], [True, False])
    np.testing.assert_array_equal(second[:, 0], [False, False, True])
    assert first[:, 1].all() and second[:, 1].all()


def test_a_new_episode_starts_with_its_link_free_of_the_last_ones_spike():
    u = np.full((3, 2, 2), 0.9)
    u[2, :, 1] = 0.45  # both arms, the step's last cycle: a spike into the next step
    links = links_with([0.0, 0.0], [0.5, 0.5], [3, 3], u)
    delivered(links, 3)
    profile = load_profile({"base": "fr3", "communication": {"jitter": 0.5, "jitter_cycles": 3}})
    links.drawn.apply([0], DrawBatch.stack([draw(profile, 7)]))  # arm 0's new episode
    links.drawn.ahead.take = quiet_draws
    links.begin_step(3)
    got = delivered(links, 3)
    assert got[:, 0].all()
    np.testing.assert_array_equal(got[:, 1], [False, False, True])  # arm 1's spike goes on
