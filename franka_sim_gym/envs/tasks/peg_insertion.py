"""PegInsertion: a square peg held in the hand, inserted into a hole with 1 mm clearance.

The industrial benchmark of Franka sim-to-real work (SERL's peg insertion, Isaac Lab's
Factory). The peg (20 mm square, 80 mm long) is in the hand at reset, squeezed by the
fingers with the env's ``grasp_force``; the fixture's 21 mm hole (scenes/peg_in_hole.xml)
is 30 mm deep and sits at a seeded spot within +-2 cm. Success is the peg's tip at the
bottom of the hole. The robot's collision thresholds make force the constraint: a peg
driven into the fixture's top or jammed in the hole trips ``cartesian_reflex``.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ...sim.rotations import rotation_to_quaternion
from .base import GoalDistanceTask
from .objects import object_space, object_state, on_table, place_object
from .push import TABLE_HOME

#: The fixture's nominal position on the table (base frame) [m] and the half-width of
#: its seeded offset in x and y.
FIXTURE = np.array([0.5, 0.0, 0.0])
FIXTURE_RANGE = 0.02
#: The peg's half width and half length [m] (scenes/peg_in_hole.xml).
PEG_HALF_WIDTH, PEG_HALF_LENGTH = 0.01, 0.04
#: Where the hand holds the peg: its centre this far beyond the TCP along the hand's
#: axis [m], so the fingertips grip its upper part and 60 mm stick out below the TCP
#: (the fingertips stay 21 mm above the fixture at full depth).
GRIP_OFFSET = 0.02
#: The hole is 30 mm deep; its bottom is the table (z = 0).
HOLE_DEPTH = 0.03


class PegInsertion(GoalDistanceTask):
    """Insert the held peg into the hole: success when its tip is within
    ``distance_threshold`` of the hole's bottom centre (full depth).

    Args:
        reward_type: "sparse" (-1 per step until inserted, else 0) or "dense" (minus the
            tip's distance to the hole's bottom).
        distance_threshold: success radius [m] (default 2 mm: the tip at the bottom; a
            tip anywhere else in the hole is at least 2 mm short of it only when it is
            off the bottom).
    """

    id_name = "PegInsertion"
    default_interface = "cartesian_velocity"
    interfaces = ("cartesian_velocity", "cartesian_pose", "joint_position", "joint_velocity")
    scene = "peg_in_hole"
    hand = "held"
    home = TABLE_HOME
    max_episode_steps = 100
    held_object = "peg"
    #: the peg's free joint in scenes/peg_in_hole.xml
    object_joint = "peg"
    #: the observation bounds a position to 2 m per axis (objects.object_space)
    farthest_distance = float(np.sqrt(3) * 4.0)

    def __init__(self, reward_type: str = "sparse", distance_threshold: float = 0.002) -> None:
        super().__init__(reward_type, distance_threshold)

    # -- episodes ------------------------------------------------------------------------------

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        """The hole's bottom centre: the fixture at a seeded offset of +-2 cm."""
        return FIXTURE + np.append(rng.uniform(-FIXTURE_RANGE, FIXTURE_RANGE, 2), 0.0)

    def reset(self, arms, rngs, physics) -> np.ndarray:
        """The fixture at a seeded spot, the peg in the hand (its axis the hand's, its tip
        60 mm below the TCP, at rest), the fingers closed on it."""
        lay = physics.layout
        # The fixture is a mocap body (scenes/peg_in_hole.xml): each arm's MjData places it.
        mocap = int(physics.model.body_mocapid[lay.scene_body["fixture"][0]])
        goals = []
        for i in arms.tolist():
            goal = self.sample_goal(rngs[i])
            data = physics.datas[i]
            # A reality draw's fixture sits off where the goal says, on its own table.
            data.mocap_pos[mocap] = fixture_of(physics, i, goal)
            site = lay.tcp_site[i]
            R_tcp = data.site_xmat[site].reshape(3, 3)
            tcp = data.site_xpos[site]
            # The peg's own z axis points up the hand (its tip, local -z, down).
            R_peg = R_tcp @ np.diag([1.0, -1.0, -1.0])
            place_object(physics, self.object_joint, i, tcp + GRIP_OFFSET * R_tcp[:, 2],
                         rotation_to_quaternion(R_peg))  # fmt: skip
            data.qpos[lay.finger_qpos_adr[i]] = PEG_HALF_WIDTH
            data.qvel[lay.finger_dof_adr[i]] = 0.0
            goals.append(goal)
        return np.stack(goals)

    # -- observations --------------------------------------------------------------------------

    def extra_space(self) -> spaces.Box:
        return object_space()

    def observe(self, physics, ee):
        state = object_state(physics, self.object_joint)
        return tip_of(state), state



def fixture_of(physics, arm: int, goal: np.ndarray) -> np.ndarray:
    """Where arm ``arm``'s fixture is when its task puts it at ``goal``: on its table
    (objects.on_table) and moved by a reality draw's fixture offset (x, y; sim/truth.py);
    ``goal`` itself for the ideal robot."""
    position = on_table(physics, arm, goal)
    if physics.truth is None:
        return position
    return position + np.append(physics.truth.fixture_offset[arm], 0.0)


def tip_of(state: np.ndarray) -> np.ndarray:
    """(n, 3) the peg's tip (the centre of its lower face: local -z) from its observed
    position and quaternion (``object_state``)."""
    w, x, y, z = (state[:, 3 + k] for k in range(4))
    # The rotation's third column (the peg's local z axis in the base frame).
    axis = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
    return state[:, :3] - PEG_HALF_LENGTH * axis
