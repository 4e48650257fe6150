"""An rl-zoo3 run's model as a policy: with the observation normalisation it trained behind.

    from franka_sim_gym.training.sb3_zoo import with_normalization
    policy = with_normalization(model, "logs/sac/FrankaFCI-v0_1/FrankaFCI-v0.zip", env)

rl-zoo3 trains an entry with ``normalize`` (the shipped file's ``FrankaFCI-v0``) behind
SB3's ``VecNormalize`` and saves its statistics as ``<run>/<env id>/vecnormalize.pkl``
beside the model ``<run>/<env id>.zip``; the model alone expects normalised
observations. ``with_normalization`` returns the model itself when there is no such
file, else a policy that normalises each observation with the saved statistics before
the model's ``predict`` (what ``rl_zoo3.enjoy`` does), for
``franka_sim_gym.training.evaluation.evaluate`` and examples/evaluate.py.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize


def normalization_file(model_path: str | Path) -> Path:
    """Where rl-zoo3 saves the normalisation of the run whose model is ``model_path``."""
    path = Path(model_path)
    return path.parent / path.name.removesuffix(".zip") / "vecnormalize.pkl"


class NormalizedPolicy:
    """An SB3 model behind ``VecNormalize`` statistics.

    ``freeze`` (default) stops the statistics' updates for good (saved ones); with
    ``freeze=False`` they stay live, for an evaluation in the middle of a training run
    (``predict`` reads them and never updates them either way)."""

    def __init__(self, model, normalization: VecNormalize, freeze: bool = True) -> None:
        self.model = model
        self.normalization = normalization
        if freeze:
            normalization.training = False

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, Any]:
        """The model's actions for the normalised observation (one or a batch)."""
        normalized = self.normalization.normalize_obs(observation)
        return self.model.predict(normalized, deterministic=deterministic)


def with_normalization(model, model_path: str | Path, env: gym.Env):
    """``model`` behind the normalisation rl-zoo3 saved beside ``model_path``, if any.

    ``env`` is one env of the id and arguments the model trained on (VecNormalize.load
    checks its spaces against the saved ones)."""
    path = normalization_file(model_path)
    if not path.is_file():
        return model
    return NormalizedPolicy(model, VecNormalize.load(str(path), DummyVecEnv([lambda: env])))
