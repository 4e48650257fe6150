"""The self-collision distances of every arm, read through each arm's link contact
sensors (sim/world.py) and contact list (sim/self_collision.py)."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.self_collision import (
    MIN_CHAIN_SEPARATION,
    close_link_pairs,
    closest_link_pair,
)
from franka_sim_gym.sim.world import SELF_COLLISION_DISTANCE


def every_contact_scanned(physics: ArmPhysics) -> np.ndarray:
    """(n,) the rule on every contact of every arm's world, no sensor consulted."""
    close = np.zeros(physics.n, dtype=bool)
    link = physics.layout.geom_link
    for i, data in enumerate(physics.datas):
        for c in range(data.ncon):
            a, b = link[data.contact.geom[c]]
            if a >= 0 and b >= 0 and abs(a - b) >= MIN_CHAIN_SEPARATION:
                close[i] |= data.contact.dist[c] < SELF_COLLISION_DISTANCE
    return close


def test_the_link_contact_sensors_miss_no_close_pair_of_any_arm():
    # Random poses over the joint ranges: a fair share folds the arm onto itself.
    physics = ArmPhysics(8, hand=True, scene="block")
    rng = np.random.default_rng(0)
    lo, hi = physics.model.jnt_range[physics.layout.qpos_adr[0]].T
    seen = 0
    for _ in range(60):
        physics.reset_arms(np.arange(8), rng.uniform(lo, hi, size=(8, 7)))
        expected = every_contact_scanned(physics)
        assert np.array_equal(close_link_pairs(physics), expected)
        seen += int(expected.sum())
        for i in np.flatnonzero(expected).tolist():
            d, a, b = closest_link_pair(physics.model, physics.datas[i], physics.layout)
            assert d < SELF_COLLISION_DISTANCE and b - a >= MIN_CHAIN_SEPARATION
    assert seen >= 20  # the poses did bring links close, on many arms


def test_an_arm_at_home_reports_no_close_pair_and_reads_no_contact_list():
    physics = ArmPhysics(3, hand=True, scene="block")
    assert not physics.link_contacts().any()  # the block on the table is no link contact
    assert not close_link_pairs(physics).any()
