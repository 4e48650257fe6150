"""What the manipulation tasks share: an object's state in the observation, placing it at
reset, and goals on (or above) the table.

Poses are in each arm's base frame (the table's z = 0 is the base plane: sim/scene.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

#: The object's entries in ``observation``: position (3), orientation as a unit
#: quaternion w, x, y, z with w >= 0 (4), linear velocity (3, base frame) and angular
#: velocity (3, the object's own axes, as MuJoCo's free joint reports it).
OBJECT_ENTRIES = 13
#: Bounds of the object's speed entries [m/s, rad/s]: far above what a push gives.
OBJECT_SPEED_BOUND = 20.0
#: Bound of the object's position entries [m] (the observation's Cartesian bound).
OBJECT_POSITION_BOUND = 2.0


def object_space() -> spaces.Box:
    """The bounds of the object's 13 observation entries."""
    p = np.full(3, OBJECT_POSITION_BOUND)
    v = np.full(6, OBJECT_SPEED_BOUND)
    high = np.concatenate([p, np.ones(4), v]).astype(np.float32)
    low = np.concatenate([-p, -np.ones(4), -v]).astype(np.float32)
    return spaces.Box(low, high, dtype=np.float32)


def object_state(physics: Any, joint: str) -> np.ndarray:
    """(n, 13) every arm's object ``joint`` (a free joint of the task's scene): position
    in its arm's base frame (its world's origin), quaternion (w >= 0), linear and angular
    velocity."""
    lay = physics.layout
    adr, dof = int(lay.scene_qpos_adr[joint][0]), int(lay.scene_dof_adr[joint][0])
    state = np.empty((physics.n, 13))
    for i, data in enumerate(physics.datas):
        state[i, :7] = data.qpos[adr : adr + 7]
        state[i, 7:] = data.qvel[dof : dof + 6]
    state[:, 3:7] *= np.where(state[:, 3:4] < 0, -1.0, 1.0)
    return state


def on_table(physics: Any, arm: int, position: np.ndarray) -> np.ndarray:
    """``position`` (on the nominal table, z = 0) on arm ``arm``'s table, whose height a
    reality draw may have moved (sim/truth.py); ``position`` itself for the ideal robot."""
    truth = physics.truth
    if truth is None:
        return position
    return position + np.array([0.0, 0.0, truth.table_height[arm]])


def place_object(physics: Any, joint: str, arm: int, position, quat=(1.0, 0.0, 0.0, 0.0)):
    """Put arm ``arm``'s object ``joint`` at ``position`` (its arm's base frame) with
    orientation ``quat`` (w, x, y, z), at rest. The caller runs ``physics.forward``."""
    lay = physics.layout
    adr = int(lay.scene_qpos_adr[joint][arm])
    dof = int(lay.scene_dof_adr[joint][arm])
    data = physics.datas[arm]
    data.qpos[adr : adr + 3] = position
    data.qpos[adr + 3 : adr + 7] = quat
    data.qvel[dof : dof + 6] = 0.0
    data.qacc_warmstart[dof : dof + 6] = 0.0
