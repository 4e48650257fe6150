"""Scripted reach policies with a trained policy's interface (SB3's ``predict``), shared by
the evaluate, deploy and in-process tests and by tests/e2e/clients/deploy_runner.py.

Both work on one observation (3,) or a batch (n, 3) alike.
"""

from __future__ import annotations

import numpy as np


class TowardTheGoal:
    """A translational action towards the goal (3 dof): ``limit`` (in unit actions) beyond
    ``reach * limit`` [m] of it, proportional within. The defaults drive a twist at full
    speed; for poses ``POSE_STEPS`` keeps each step's target near the reference (libfranka's
    pose limiter overshoots a far target: docs/env.md)."""

    def __init__(self, reach: float = 0.1, limit: float = 1.0) -> None:
        self.reach = reach
        self.limit = limit

    def predict(self, obs: dict, deterministic: bool = True):
        error = obs["desired_goal"].astype(np.float64) - obs["achieved_goal"]
        return np.clip(error / self.reach, -self.limit, self.limit).astype(np.float32), None


#: TowardTheGoal's arguments for Cartesian pose steps (a unit action: a 5 cm target): 30 %
#: of the error a step, at most 1.5 cm: 20 of 20 in-process reaches, no reflex, where
#: the twist's full-scale steps trip 29 (the pose limiter's overshoot) in 3 of 20.
POSE_STEPS = {"reach": 0.05 / 0.3, "limit": 0.3}


class Still:
    """A zero twist: the arm stays where the episode started."""

    def predict(self, obs: dict, deterministic: bool = True):
        return np.zeros(np.shape(obs["desired_goal"]), np.float32), None


class Fixed:
    """The same action for every observation: one row per row of a batch, or one action
    for one observation (SB3's ``predict``), in ``dtype``."""

    def __init__(self, action, dtype=np.float32) -> None:
        self.action = np.asarray(action, dtype=dtype)

    def predict(self, observation: dict, deterministic: bool = True):
        obs = observation["observation"]
        if obs.ndim == 1:
            return self.action.copy(), None
        return np.tile(self.action, (len(obs), 1)), None
