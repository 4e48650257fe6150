"""A policy's success rate and reflex rate over N episodes run side by side.

    from franka_sim_gym.training.evaluation import evaluate
    result = evaluate(model, "FrankaFCICartesianVelocity-v0", {"cartesian_dof": 3}, 100, seed=0)
    result["success_rate"], result["reflex_rate"], result["reflexes_by_error"]

Any policy with SB3's ``predict(obs, deterministic=True) -> (actions, state)`` over a
batch of observations: an SB3 model, or a small wrapper around another framework's
(``examples/train_rllib.py`` wraps an RLlib module). Needs gymnasium and numpy only.
"""

from __future__ import annotations

from typing import Any, Protocol

import gymnasium as gym
import numpy as np

#: The first episode seed of the training scripts' evaluations (examples/train_sb3.py,
#: train_bc.py, train_rllib.py, where_it_fails.py): above every recorded
#: demonstration's and DAgger round's seeds, so no evaluation episode was trained on.
EVALUATION_SEED = 10_000


class Policy(Protocol):
    """What ``evaluate`` calls: SB3's ``predict`` signature, on a batch of observations."""

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, Any]:
        """Actions for the batch (one row per arm), and any recurrent state."""
        ...


def evaluate(
    policy: Policy, env_id: str, env_kwargs: dict, episodes: int, seed: int
) -> dict[str, Any]:
    """One deterministic episode per arm of a batched env of ``episodes`` arms.

    Arm i is seeded ``seed + i``: the same episodes as ``episodes`` single envs. Returns
    the success rate, the reflex rate, the reflexes by the robot's error name and the
    mean control_command_success_rate at the last step of the episodes that did not end
    in a reflex (a reflex stops the motion, and the robot reports 0.0 between motions;
    NaN when every episode ended in one). An episode that ended in a reflex is not a
    success, even when the reflex caught the arm within the goal's radius (the env's
    ``is_success`` judges the position only): on a robot, that reach failed.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    envs = gym.make_vec(
        env_id, num_envs=episodes, vectorization_mode="vector_entry_point", **env_kwargs
    )
    obs, _ = envs.reset(seed=seed)
    ended = np.zeros(episodes, dtype=bool)
    success = np.zeros(episodes, dtype=bool)
    reflex = np.zeros(episodes, dtype=bool)
    link = np.zeros(episodes)
    by_error: dict[str, int] = {}
    while not ended.all():
        actions, _ = policy.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = envs.step(actions)
        done = (terminated | truncated) & ~ended
        for i in np.flatnonzero(done).tolist():
            success[i] = bool(info["is_success"][i]) and not terminated[i]
            link[i] = float(info["control_command_success_rate"][i])
            if terminated[i]:
                reflex[i] = True
                for name in info["reflex_reason"][i]:
                    by_error[name] = by_error.get(name, 0) + 1
        ended |= done
    envs.close()
    return {
        "success_rate": float(success.mean()),
        "reflex_rate": float(reflex.mean()),
        "reflexes_by_error": by_error,
        "link_success_rate": float(link[~reflex].mean()) if (~reflex).any() else float("nan"),
    }
