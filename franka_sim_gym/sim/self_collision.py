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

from collections.abc import Sequence

import mujoco
import numpy as np

from .world import SELF_COLLISION_DISTANCE, ArmLayout

#: docs/fci-behaviour.md "self_collision_avoidance_violation (2)": only links at least three apart
#: in the chain are monitored.
MIN_CHAIN_SEPARATION = 3


def close_link_pairs(
    model: mujoco.MjModel,
    datas: Sequence[mujoco.MjData],
    layout: ArmLayout,
    distance: float = SELF_COLLISION_DISTANCE,
) -> np.ndarray:
    """(n,) bool: arm i (its own MjData ``datas[i]``) has a monitored link pair closer
    than ``distance``.

    Costs next to nothing for an arm whose world reports no contact at all (the usual
    case without objects); the contacts of the others are judged in one pass.
    """
    close = np.zeros(len(datas), dtype=bool)
    geoms, dists, arms = [], [], []
    for i, data in enumerate(datas):
        if data.ncon:
            contact = data.contact
            geoms.append(contact.geom)
            dists.append(contact.dist)
            arms.append(np.full(len(contact.dist), i))
    if not geoms:
        return close
    geoms = np.concatenate(geoms)
    link = layout.geom_link[geoms]
    monitored = (
        (link[:, 0] >= 0)
        & (link[:, 1] >= 0)
        & (np.abs(link[:, 0] - link[:, 1]) >= MIN_CHAIN_SEPARATION)
        & (np.concatenate(dists) < distance)
    )
    close[np.concatenate(arms)[monitored]] = True
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
