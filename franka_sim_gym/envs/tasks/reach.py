"""Reach: bring the end effector (O_T_EE's position) within ``distance_threshold`` of a goal."""

from __future__ import annotations

import numpy as np

from .base import GoalDistanceTask

#: Goals are drawn uniformly from this box in the robot's base frame [m]: in
#: front of the arm, inside its workspace, clear of the base and the floor, and
#: short of the stretched-arm singularity (joint 4 straight): with the far corner at
#: 0.65 m the default policy reached a goal at (0.64, 0.18, 0.64) with an IK joint-4
#: acceleration of 10.04 rad/s^2 and tripped 30 in 1 of 100 evaluation episodes.
GOAL_LOW = np.array([0.30, -0.30, 0.20])
GOAL_HIGH = np.array([0.60, 0.30, 0.60])


class Reach(GoalDistanceTask):
    """Goal-conditioned reach with a sparse or dense reward; nothing in the scene.

    Args:
        reward_type: "sparse" (-1 per step until within the threshold, else 0) or
            "dense" (minus the distance to the goal).
        distance_threshold: success radius [m] (default 5 cm).
    """

    id_name = ""  # FrankaFCI-v0, FrankaFCIJointPosition-v0, ...
    default_interface = "joint_position"
    #: the box's diagonal, plus 1 m of margin for an end effector outside the box
    farthest_distance = float(np.linalg.norm(GOAL_HIGH - GOAL_LOW)) + 1.0

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(GOAL_LOW, GOAL_HIGH)
