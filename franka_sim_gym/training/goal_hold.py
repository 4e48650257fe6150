"""A Cartesian-velocity policy that holds still once its task is done.

A clone does not learn where the task ends: the Push solver stops once the block is
within 1 cm of its goal, and its clones, which see the block near the goal but not the
solver's stop, drift on or go round again, with the arm folded near the base where the
robot's IK refuses what they ask (``cartesian_motion_generator_joint_acceleration_
discontinuity``, docs/demonstrations.md "The hold"). ``GoalHold`` is the rule a robot
programmer puts after a policy (SERL and panda-gym end the episode at success for the
same reason): while the object is within ``radius`` of its goal (the observation's
``achieved_goal`` and ``desired_goal``), the commanded velocity is zero; the hand's
width, when the action has one, is the policy's. Once the object leaves the radius,
the policy acts again.
"""

from __future__ import annotations

from typing import Any

import numpy as np


class GoalHold:
    """``policy`` (SB3's ``predict`` over a batch; Cartesian velocity actions) with its
    velocity zeroed wherever the achieved goal is within ``radius`` of the desired goal.

    Args:
        policy: anything with SB3's ``predict``.
        radius: the distance [m] under which the hand holds still; positive and finite
            (on Push, 0.03 m: inside the task's 5 cm success radius).
        velocity_dims: how many leading action entries are the Cartesian velocity (3 or
            6, the env's ``cartesian_dof``); the entries after them (the hand's width)
            pass through.
    """

    def __init__(self, policy: Any, radius: float, velocity_dims: int = 3) -> None:
        if not (np.isfinite(radius) and radius > 0.0):
            raise ValueError(f"radius must be a positive distance [m], got {radius!r}")
        if velocity_dims not in (3, 6):
            raise ValueError(f"velocity_dims must be 3 or 6, got {velocity_dims!r}")
        self.policy, self.radius, self.velocity_dims = policy, float(radius), velocity_dims

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The policy's actions, their velocity zero where the task is done."""
        actions, state = self.policy.predict(observation, deterministic=deterministic)
        offset = np.asarray(observation["achieved_goal"]) - np.asarray(observation["desired_goal"])
        done = np.linalg.norm(offset, axis=-1) < self.radius
        held = np.array(actions, copy=True)  # (the policy's dtype kept)
        held[done, ..., : self.velocity_dims] = 0.0
        return held, state
