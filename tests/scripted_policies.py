"""Scripted reach policies with a trained policy's interface (SB3's ``predict``), shared by
the evaluate, deploy and in-process tests and by tests/clients/deploy_runner.py.

Both work on one observation (3,) or a batch (n, 3) alike.
"""

from __future__ import annotations

import numpy as np


class TowardTheGoal:
    """A translational twist towards the goal (3 dof): full speed beyond ``reach`` [m] of
    it, proportional within."""

    def __init__(self, reach: float = 0.1) -> None:
        self.reach = reach

    def predict(self, obs: dict, deterministic: bool = True):
        error = obs["desired_goal"].astype(np.float64) - obs["achieved_goal"]
        return np.clip(error / self.reach, -1.0, 1.0).astype(np.float32), None


class Still:
    """A zero twist: the arm stays where the episode started."""

    def predict(self, obs: dict, deterministic: bool = True):
        return np.zeros(np.shape(obs["desired_goal"]), np.float32), None
