"""Reach: bring the end effector (O_T_EE's position) within ``distance_threshold`` of a goal."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Goals are drawn uniformly from this box in the robot's base frame [m]: in
#: front of the arm, inside its workspace, clear of the base and the floor, and
#: short of the stretched-arm singularity (joint 4 straight): with the far corner at
#: 0.65 m the default policy reached a goal at (0.64, 0.18, 0.64) with an IK joint-4
#: acceleration of 10.04 rad/s^2 and tripped 30 in 1 of 100 evaluation episodes.
GOAL_LOW = np.array([0.30, -0.30, 0.20])
GOAL_HIGH = np.array([0.60, 0.30, 0.60])


@dataclass
class Reach:
    """Goal-conditioned reach with a sparse or dense reward.

    Args:
        reward_type: "sparse" (-1 per step until within the threshold, else 0) or
            "dense" (minus the distance to the goal).
        distance_threshold: success radius [m] (default 5 cm).
    """

    reward_type: str = "sparse"
    distance_threshold: float = 0.05

    def __post_init__(self) -> None:
        if self.reward_type not in ("sparse", "dense"):
            raise ValueError(f"reward_type must be 'sparse' or 'dense', got {self.reward_type!r}")

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(GOAL_LOW, GOAL_HIGH)

    def compute_reward(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """Vectorised over a leading batch axis, as SB3's HER calls it.

        ``info`` is one step's info dict, a sequence of them (HER passes the stored
        ones), or a numeric array of their ``reflex_penalty`` values (what
        ``envs/sb3_her.py`` stores). The charge is added, so a step's own transition gives
        the step's reward and a relabelled reflex step stays charged.
        """
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        if self.reward_type == "sparse":
            reward = -(d > self.distance_threshold).astype(np.float32)
        else:
            reward = -d.astype(np.float32)
        penalty = _penalty(info)
        if penalty is None:
            return reward
        return (reward + np.reshape(penalty, np.shape(reward))).astype(np.float32)

    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return d <= self.distance_threshold

    @property
    def worst_step_reward(self) -> float:
        """The lowest reward one step can give (for the reflex penalty)."""
        if self.reward_type == "sparse":
            return -1.0
        return -float(np.linalg.norm(GOAL_HIGH - GOAL_LOW)) - 1.0


def _penalty(info) -> np.ndarray | float | None:
    """The reflex_penalty of one info dict, of a sequence of them, or the penalties
    themselves as a numeric array (None: no infos)."""
    if info is None:
        return None
    if isinstance(info, dict):
        return np.asarray(info.get("reflex_penalty", 0.0), dtype=np.float64)
    if isinstance(info, np.ndarray) and info.dtype.kind in "fiu":
        return info.astype(np.float64)
    rows = list(info)
    if not rows or not isinstance(rows[0], dict):
        return None
    return np.array([row.get("reflex_penalty", 0.0) for row in rows], dtype=np.float64)
