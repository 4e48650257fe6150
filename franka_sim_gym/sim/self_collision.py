"""Distances between the arm's own links, read off MuJoCo's contact list.

The safety controller's self_collision_avoidance_violation (2) fires when two
links at least three apart in the chain come within 50 mm (docs/fci-behaviour.md
"self_collision_avoidance_violation (2)"). The arm's
collision geoms carry a contact *reporting* band (models/fr3.xml: gap without
margin, so a pair is listed in data.contact out to 50 mm with no constraint
row): the physics and its contact forces are unchanged, only MuJoCo's field of
view widens. Neighbours and once-removed pairs are not monitored, nor the hand
(geom_link = -1): link0/link1 and link5/link7 are excluded in the model itself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .layout import MIN_CHAIN_SEPARATION, ArmLayout
from .world import SELF_COLLISION_DISTANCE

if TYPE_CHECKING:
    from .arm import ArmPhysics


def close_link_pairs(physics: ArmPhysics, distance: float = SELF_COLLISION_DISTANCE) -> np.ndarray:
    """(n,) bool: arm i (its own MjData ``physics.datas[i]``) has a monitored link pair
    closer than ``distance``.

    Reads the contact lists of the arms whose link contact sensors count a contact
    (``physics.link_contacts``: none, the usual case) and judges them in one pass.
    """
    close = np.zeros(physics.n, dtype=bool)
    if not physics.any_link_contact():
        return close
    arms = np.flatnonzero(physics.link_contacts())
    geoms, dists, rows = [], [], []
    for i in arms.tolist():
        contact = physics.datas[i].contact
        geoms.append(contact.geom)
        dists.append(contact.dist)
        rows.append(np.full(len(contact.dist), i))
    link = physics.layout.geom_link[np.concatenate(geoms)]
    monitored = (
        (link[:, 0] >= 0)
        & (link[:, 1] >= 0)
        & (np.abs(link[:, 0] - link[:, 1]) >= MIN_CHAIN_SEPARATION)
        & (np.concatenate(dists) < distance)
    )
    close[np.concatenate(rows)[monitored]] = True
    return close


def closest_link_pair(
    model: mujoco.MjModel, data: mujoco.MjData, layout: ArmLayout
) -> tuple[float, int, int] | None:
    """For the log line: (distance, link a, link b) of the closest monitored pair of the
    arm whose MjData is ``data``."""
    best = None
    for c in range(data.ncon):
        g1, g2 = data.contact.geom[c]
        a, b = int(layout.geom_link[g1]), int(layout.geom_link[g2])
        if a < 0 or b < 0 or abs(a - b) < MIN_CHAIN_SEPARATION:
            continue
        d = float(data.contact.dist[c])
        if best is None or d < best[0]:
            best = (d, min(a, b), max(a, b))
    return best
