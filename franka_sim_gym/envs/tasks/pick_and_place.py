"""PickAndPlace: the 4 cm block grasped with the Franka Hand and placed at a goal that may
be in the air.

panda-gym's PickAndPlace and Gymnasium-Robotics' FetchPickAndPlace. The grasp is physical:
the fingers are MuJoCo bodies on the force-limited servo (the env's ``grasp_force``), the
block is held by friction, and its weight reaches the arm's measured torques; while held
it is the robot's configured load unless ``configure_load=False`` (docs/env.md).
"""

from __future__ import annotations

import numpy as np

from .push import CENTRE, HALF, RANGE, Push

#: Highest goal above the block's resting height [m]: panda-gym's goal_z_range.
LIFT = 0.2


class PickAndPlace(Push):
    """Bring the block's centre within ``distance_threshold`` of a goal; half the goals
    lie on the table, half up to ``LIFT`` above it (as Fetch draws them).

    Args:
        reward_type, distance_threshold: as Push's.
    """

    id_name = "PickAndPlace"
    hand = "grasp"
    held_object = "block"
    #: ``safety_box="task"``: Push's, with the floor at 1.6 cm (the open fingertips
    #: touch the table with the TCP at ~1.2 cm; the solver grasps at 2 cm) and the
    #: ceiling over the highest goal
    safety_box = ((0.33, -0.20, 0.016), (0.70, 0.20, 0.30))

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        xy = rng.uniform(CENTRE - RANGE, CENTRE + RANGE)
        air, lift = rng.uniform(), rng.uniform(0.0, LIFT)
        return np.append(xy, HALF + (lift if air < 0.5 else 0.0))
