"""rl-zoo3 and this package: the batched env under an rl-zoo3 run, and the run's model as a
policy with the observation normalisation it trained behind.

    # the shipped file's entries name it as their vec_env_wrapper:
    #   vec_env_wrapper: franka_sim_gym.training.sb3_zoo.BatchedArms
    from franka_sim_gym.training.sb3_zoo import with_normalization
    policy = with_normalization(model, "logs/sac/FrankaFCI-v0_1/FrankaFCI-v0.zip", env)

rl-zoo3 steps an entry's ``n_envs`` arms as a ``DummyVecEnv`` of single envs: one
controller call and one MuJoCo step per arm per cycle. ``BatchedArms``, named as the
entry's ``vec_env_wrapper``, hands it the native batched env of the same id, arguments
and number of arms instead (one controller call per cycle for all of them: docs/env.md),
with SB3's ``VecMonitor`` for the episode statistics rl-zoo3 logs.

rl-zoo3 trains an entry with ``normalize`` behind SB3's ``VecNormalize`` and saves its
statistics as ``<run>/<env id>/vecnormalize.pkl`` beside the model ``<run>/<env id>.zip``;
the model alone expects normalised observations. ``with_normalization`` returns the model
itself when there is no such file, else a policy that normalises each observation with
the saved statistics before the model's ``predict`` (what ``rl_zoo3.enjoy`` does), for
``franka_sim_gym.training.evaluation.evaluate`` and examples/evaluate.py.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import (
    DummyVecEnv,
    VecEnv,
    VecEnvWrapper,
    VecMonitor,
    VecNormalize,
)

from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv


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


class BatchedArms(VecEnvWrapper):
    """The native batched env in place of the vector env rl-zoo3 built: an entry's
    ``vec_env_wrapper``, with the entry's env arguments as its own.

    rl-zoo3 builds ``n_envs`` single envs of the entry's id (each behind its ``Monitor``)
    and hands their vector env to the wrapper; this one closes them and steps
    ``FrankaFCISB3VecEnv`` of as many arms behind SB3's ``VecMonitor`` (the episode
    returns, lengths and successes rl-zoo3 logs). The arms' arguments: the id's
    registered ones, over them ``env_kwargs`` (the entry's, given in the file as the
    wrapper's arguments), over those whatever rl-zoo3 gave the single envs beyond the
    registration (``--env-kwargs``). The entry's arguments are the wrapper's because
    rl-zoo3 2.9.2 builds its evaluation env (``--eval-freq``) without the entry's
    ``env_kwargs`` (``ExperimentManager`` copies them to the evaluation only when
    ``--env-kwargs`` is given): as the wrapper's, training, evaluation and
    ``rl_zoo3.enjoy`` all step the same env. The seeds SB3 gives the model reach the arms
    as they would the single envs (arm i: seed + i). rl-zoo3's per-env ``monitor.csv``
    files stay empty.
    """

    def __init__(self, venv: VecEnv, **env_kwargs: Any) -> None:
        spec = venv.get_attr("spec", [0])[0]
        kwargs = {**gym.spec(spec.id).kwargs, **env_kwargs, **arguments_given(spec)}
        arms = venv.num_envs
        venv.close()
        batched = FrankaFCISB3VecEnv(arms, **kwargs)
        super().__init__(VecMonitor(batched, info_keywords=("is_success",)))

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        return self.venv.step_wait()


def arguments_given(spec: gym.envs.registration.EnvSpec) -> dict[str, Any]:
    """The arguments an env of ``spec`` was made with beyond its id's registration
    (``gym.make``'s ``max_episode_steps`` among them). A value given equal to the
    registered one is indistinguishable from it and not returned."""
    registered = gym.spec(spec.id)
    given = {k: v for k, v in spec.kwargs.items() if registered.kwargs.get(k, _UNSET) != v}
    if spec.max_episode_steps != registered.max_episode_steps:
        given["max_episode_steps"] = spec.max_episode_steps
    return given


#: a value no registered argument has (arguments_given)
_UNSET = object()


def entry_env_kwargs(entry: dict[str, Any]) -> dict[str, Any]:
    """The env arguments an rl-zoo3 hyperparameter entry trains with: its ``BatchedArms``
    wrapper's arguments (the shipped file's entries), over its ``env_kwargs`` if any."""
    kwargs = dict(entry.get("env_kwargs") or {})
    wrappers = entry.get("vec_env_wrapper") or []
    for wrapper in wrappers if isinstance(wrappers, list) else [wrappers]:
        if isinstance(wrapper, dict):
            for name, arguments in wrapper.items():
                if name.endswith(".BatchedArms"):
                    kwargs.update(arguments or {})
    return kwargs
