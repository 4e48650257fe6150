"""Streams drawn ahead (reality/ahead.py): a robot's samples are its own generator's in
order, across block refills, whatever the other robots do and whenever they start."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.reality.ahead import BLOCK, Ahead


def uniform(rng, i, count):
    return rng.random((count, 2))


def test_a_robot_reads_its_own_stream_in_order_across_refills_and_other_resets():
    ahead = Ahead(3, 2, uniform)
    ahead.reseed([0, 1, 2], [np.random.default_rng(s) for s in (0, 1, 2)])
    expected = np.random.default_rng(1).random((3 * BLOCK, 2))
    seen = []
    for cycle in range(3 * BLOCK):
        if cycle in (17, BLOCK + 40):  # another robot's episodes start over
            ahead.reseed([2], [np.random.default_rng(cycle)])
        seen.append(ahead.current()[1].copy())
        assert np.array_equal(ahead.current()[1], seen[-1])  # read again: the same
        ahead.advance()
    np.testing.assert_array_equal(np.array(seen), expected)


def test_a_robot_starting_late_reads_what_it_would_alone():
    alone = Ahead(1, 2, uniform)
    alone.reseed([0], [np.random.default_rng(9)])
    batch = Ahead(2, 2, uniform)
    batch.reseed([0, 1], [np.random.default_rng(3), np.random.default_rng(4)])
    for _ in range(BLOCK - 5):
        batch.advance()
    batch.reseed([1], [np.random.default_rng(9)])  # robot 1's episode starts here
    for _ in range(2 * BLOCK):
        np.testing.assert_array_equal(batch.current()[1], alone.current()[0])
        batch.advance()
        alone.advance()


def test_take_reads_what_as_many_advances_read():
    # Counts that end before a refill, at one (cycle 256: robot 0's; 286: robot 1's), one
    # cycle past one (the BLOCK from cycle 287 ends at 543, past both refills at 542) and
    # over several, and a reseed between two takes.
    taken, stepped = Ahead(2, 2, uniform), Ahead(2, 2, uniform)
    for ahead in (taken, stepped):
        ahead.reseed([0], [np.random.default_rng(5)])
        for _ in range(30):
            ahead.advance()
        ahead.reseed([1], [np.random.default_rng(6)])
    for count in (1, 40, BLOCK - 71, 30, 1, BLOCK, 2 * BLOCK + 3, 40):
        out = taken.take(count)
        expected = []
        for _ in range(count):
            expected.append(stepped.current().copy())
            stepped.advance()
        np.testing.assert_array_equal(out, np.array(expected))
        np.testing.assert_array_equal(taken.current(), stepped.current())
        if count == 30:
            for ahead in (taken, stepped):
                ahead.reseed([0], [np.random.default_rng(7)])


def test_next_reads_what_advance_then_current_read():
    nexted, stepped = Ahead(2, 2, uniform), Ahead(2, 2, uniform)
    for ahead in (nexted, stepped):
        ahead.reseed([0, 1], [np.random.default_rng(3), np.random.default_rng(4)])
    for _ in range(2 * BLOCK + 5):  # across refills and the ring's wrap
        stepped.advance()
        np.testing.assert_array_equal(nexted.next(), stepped.current())
