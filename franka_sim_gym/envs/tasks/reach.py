"""Reach: bring the end effector (O_T_EE's position) within ``distance_threshold`` of a goal."""

from __future__ import annotations

import numpy as np

from .base import Task, charged

#: Goals are drawn uniformly from this box in the robot's base frame [m]: in
#: front of the arm, inside its workspace, clear of the base and the floor, and
#: short of the stretched-arm singularity (joint 4 straight): with the far corner at
#: 0.65 m the default policy reached a goal at (0.64, 0.18, 0.64) with an IK joint-4
#: acceleration of 10.04 rad/s^2 and tripped 30 in 1 of 100 evaluation episodes.
GOAL_LOW = np.array([0.30, -0.30, 0.20])
GOAL_HIGH = np.array([0.60, 0.30, 0.60])


class Reach(Task):
    """Goal-conditioned reach with a sparse or dense reward; nothing in the scene.

    Args:
        reward_type: "sparse" (-1 per step until within the threshold, else 0) or
            "dense" (minus the distance to the goal).
        distance_threshold: success radius [m] (default 5 cm).
    """

    id_name = ""  # FrankaFCI-v0, FrankaFCIJointPosition-v0, ...
    default_interface = "joint_position"

    def __init__(self, reward_type: str = "sparse", distance_threshold: float = 0.05) -> None:
        if reward_type not in ("sparse", "dense"):
            raise ValueError(f"reward_type must be 'sparse' or 'dense', got {reward_type!r}")
        if not distance_threshold > 0:
            raise ValueError(f"distance_threshold must be > 0, got {distance_threshold!r}")
        self.reward_type = reward_type
        self.distance_threshold = float(distance_threshold)

    def __repr__(self) -> str:
        threshold = self.distance_threshold
        return f"Reach(reward_type={self.reward_type!r}, distance_threshold={threshold})"

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(GOAL_LOW, GOAL_HIGH)

    def compute_reward(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """Vectorised over a leading batch axis, as SB3's HER calls it.

        ``info`` is one step's info dict, a sequence of them (HER passes the stored
        ones), or a numeric array of their ``reflex_penalty`` values (what the training
        package's HER buffer stores). The charge is added, so a step's own transition
        gives the step's reward and a relabelled reflex step stays charged.
        """
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        if self.reward_type == "sparse":
            reward = -(d > self.distance_threshold).astype(np.float32)
        else:
            reward = -d.astype(np.float32)
        return charged(reward, info)

    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return d <= self.distance_threshold

    @property
    def worst_step_reward(self) -> float:
        """The lowest reward one step can give (for the reflex penalty)."""
        if self.reward_type == "sparse":
            return -1.0
        return -float(np.linalg.norm(GOAL_HIGH - GOAL_LOW)) - 1.0
