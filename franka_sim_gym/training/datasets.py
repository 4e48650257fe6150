"""Demonstrations as Minari datasets: record any policy's episodes, read them back.

    from franka_sim_gym.training.datasets import record
    dataset = record("franka/push-scripted-v0", "FrankaFCIPush-v0", policy, episodes=50)

    dataset = minari.load_dataset("franka/push-scripted-v0")
    env = dataset.recover_environment()      # the id and its arguments, rebuilt
    episode = dataset[0]                     # minari.EpisodeData
    env.reset(seed=episode_seed(dataset, episode.id))
    for action in episode.actions: env.step(action)   # the same episode, bit for bit

The episodes run side by side in the native batched env (``num_envs`` arms at a time,
arm i of a batch seeded ``seed + its episode number``); each arm's episode is stored as
the single-env episode it is bit for bit (docs/env.md, "Native vector env"), with its
seed, so ``replay`` (or ``recover_environment()``, ``reset(seed=...)`` and the stored
actions) gives the same observations, rewards and infos. Nothing is written until every
episode has run: bad input (a malformed or existing dataset id, an unknown env id,
arguments the spec cannot store, a policy's action outside the action space) raises a
``ValueError`` naming the problem and leaves no dataset behind.

Datasets live where Minari keeps them: ``$MINARI_DATASETS_PATH``, else
``~/.minari/datasets`` (Minari's rule). Needs the ``datasets`` extra (minari with its
HDF5 storage).

What an episode holds (``minari.EpisodeData``): ``observations`` (the Dict observation,
one more entry than actions: the reset's), ``actions`` as the env received them (in the
action space's dtype), ``rewards``, ``terminations`` (a reflex), ``truncations`` (the
time limit), and ``infos``, the env's info at the reset and after every step with each
tuple of the robot's error names (``errors``, ``reflex_reason``, ``violations``) stored
as one comma-separated string (``names`` splits it back): ``is_success``,
``reflex_penalty``, ``robot_mode``, ``joint_contact`` (7), ``cartesian_contact`` (6),
``O_F_ext_hat_K`` (6), ``control_command_success_rate``, ``lost_cycles``,
``longest_lost_run``, ``cycles``.

``noise`` records a noise-injected demonstration (DART: Laskey et al., 2017, "DART:
Noise Injection for Robust Imitation Learning"): each step the policy's action plus
Gaussian noise is what the env executes and ``actions`` holds; the policy's own action
at that state, the label a learner imitates, is the info ``demonstrator_action`` after
the step (NaN at the reset). A learner fitted to the labels has seen the demonstrator
recover from the errors it will itself make; a learner fitted to noise-free episodes
has seen only the demonstrator's own path (docs/demonstrations.md).
"""

from __future__ import annotations

import dataclasses
import shutil
import warnings
from collections import Counter
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from franka_sim_gym.envs.infos import info_row

#: how a tuple of the robot's error names is stored (no error name has a comma)
SEPARATOR = ","


def names(value: Any) -> tuple[str, ...]:
    """The tuple of error names of one stored entry (a str, or HDF5's bytes)."""
    text = value.decode() if isinstance(value, bytes) else str(value)
    return tuple(text.split(SEPARATOR)) if text else ()


def encode_info(row: dict[str, Any]) -> dict[str, Any]:
    """One step's info as Minari's HDF5 storage takes it: every value fixed in type and
    shape across the episode; a tuple of error names (of any length) as one string."""
    return {
        key: SEPARATOR.join(value) if isinstance(value, tuple) else value
        for key, value in row.items()
    }


def dataset_spec(env_id: str, env_kwargs: dict | None = None) -> gym.envs.registration.EnvSpec:
    """``env_id``'s spec with ``env_kwargs`` merged over its arguments (a
    ``max_episode_steps`` among them sets the spec's time limit too): what the dataset
    stores and ``recover_environment()`` makes."""
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as error:
        raise ValueError(f"unknown env id {env_id!r}: {error}") from None
    kwargs = {**spec.kwargs, **(env_kwargs or {})}
    steps = kwargs.get("max_episode_steps", spec.max_episode_steps)
    spec = dataclasses.replace(spec, kwargs=kwargs, max_episode_steps=steps)
    try:
        spec.to_json()
    except (ValueError, TypeError) as error:
        raise ValueError(
            f"env arguments {env_kwargs!r} cannot be stored in a dataset (JSON only): {error}"
        ) from None
    return spec


def dataset_path(dataset_id: str):
    """Where Minari keeps ``dataset_id`` (``$MINARI_DATASETS_PATH`` or its default)."""
    from minari.storage import get_dataset_path

    return get_dataset_path(dataset_id)


def check_new_id(dataset_id: str) -> None:
    """A ``ValueError`` if ``dataset_id`` is malformed or names a dataset that exists."""
    from minari.dataset.minari_dataset import parse_dataset_id

    parse_dataset_id(dataset_id)  # ValueError naming the form: (namespace/)name-vN
    if dataset_path(dataset_id).exists():
        raise ValueError(
            f"dataset {dataset_id!r} exists (at {dataset_path(dataset_id)}): "
            "pick another id or version, or delete it with minari.delete_dataset"
        )


def checked_actions(
    actions: Any, space: gym.spaces.Box, rows: np.ndarray, who: str = "policy"
) -> np.ndarray:
    """``who``'s (n, dim) actions in the action space's dtype, or a ``ValueError``
    naming the first arm whose action is outside the space (rows: its episode numbers)."""
    n = len(rows)
    # a copy: a policy that reuses one output array must not rewrite the stored steps
    cast = np.array(actions, dtype=space.dtype, copy=True)
    if cast.shape != (n, *space.shape):
        raise ValueError(
            f"the {who} returned actions of shape {np.shape(actions)}, expected "
            f"{(n, *space.shape)} (one row per arm)"
        )
    bad = ~(np.isfinite(cast) & (cast >= space.low) & (cast <= space.high)).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"the {who}'s action {cast[i].tolist()} (episode {int(rows[i])}) is outside "
            f"the action space [{space.low.tolist()}, {space.high.tolist()}]"
        )
    return cast


class _Episode:
    """One arm's episode as it runs: the lists Minari's EpisodeBuffer takes."""

    def __init__(self, seed: int, obs: dict, info: dict) -> None:
        self.seed = seed
        self.observations = {key: [value] for key, value in obs.items()}
        self.infos = {key: [value] for key, value in info.items()}
        self.actions: list[np.ndarray] = []
        self.rewards: list[float] = []
        self.terminations: list[bool] = []
        self.truncations: list[bool] = []

    def add(self, obs, action, reward, terminated, truncated, info) -> None:
        for key, value in obs.items():
            self.observations[key].append(value)
        for key, value in info.items():
            self.infos[key].append(value)
        self.actions.append(action)
        self.rewards.append(float(reward))
        self.terminations.append(bool(terminated))
        self.truncations.append(bool(truncated))

    def buffer(self, episode_id: int):
        from minari.data_collector import EpisodeBuffer

        return EpisodeBuffer(
            id=episode_id,
            seed=self.seed,
            observations={k: np.stack(v) for k, v in self.observations.items()},
            actions=np.stack(self.actions),
            rewards=self.rewards,
            terminations=self.terminations,
            truncations=self.truncations,
            infos={
                k: np.stack(v) if isinstance(v[0], np.ndarray) else v for k, v in self.infos.items()
            },
        )


#: the info that holds the demonstrator's action of a noise-injected step
DEMONSTRATOR_ACTION = "demonstrator_action"
#: the second word of each episode's noise seed ([episode seed, this]): "NOISE" in ASCII
NOISE_STREAM = 0x4E4F495345


def noise_scale(noise: float | Sequence[float] | None, space: gym.spaces.Box) -> np.ndarray | None:
    """``noise`` (a standard deviation, or one per action dimension) as an array of the
    action's shape; None for no noise; a ``ValueError`` naming a bad value."""
    if noise is None:
        return None
    try:
        scale = np.broadcast_to(np.asarray(noise, dtype=np.float64), space.shape).copy()
    except ValueError:
        raise ValueError(
            f"noise {noise!r} is neither one standard deviation nor one per action "
            f"dimension ({space.shape[0]})"
        ) from None
    if not (np.isfinite(scale) & (scale >= 0)).all():
        raise ValueError(f"noise must be finite and >= 0, got {noise!r}")
    return scale if scale.any() else None


def run_episodes(
    spec: gym.envs.registration.EnvSpec,
    policy: Callable,
    episodes: int,
    seed: int,
    num_envs: int,
    noise: float | Sequence[float] | None = None,
    executor: Callable[[dict], np.ndarray] | None = None,
) -> list[_Episode]:
    """``episodes`` episodes of ``policy`` in batches of ``num_envs`` arms, in memory;
    with ``executor``, its actions are executed and the policy's are the labels; with
    ``noise``, the executed actions get Gaussian noise added (each episode's from its
    own generator, seeded ``[episode seed, NOISE_STREAM]``: the same episode seed, the
    same noise, whatever the batch), clipped to the space."""
    out: list[_Episode] = []
    for start in range(0, episodes, num_envs):
        n = min(num_envs, episodes - start)
        rows = np.arange(start, start + n)
        envs = gym.make_vec(spec, num_envs=n, vectorization_mode="vector_entry_point")
        try:
            space = envs.single_action_space
            scale = noise_scale(noise, space)
            # One noise stream per episode, from its seed and a tag: the env seeds arm i
            # with default_rng(seed + i) too, and the noise must not replay those draws
            # nor depend on which batch the episode ran in.
            rngs = [np.random.default_rng([seed + start + i, NOISE_STREAM]) for i in range(n)]
            obs, info = envs.reset(seed=seed + start)
            for actor in (policy, executor):
                if hasattr(actor, "reset"):
                    actor.reset(np.arange(n))
            labelled = scale is not None or executor is not None
            labels = {}
            if labelled:  # no action before the reset
                labels = {DEMONSTRATOR_ACTION: np.full(space.shape, np.nan, space.dtype)}
            batch = [
                _Episode(
                    seed + start + i,
                    {k: v[i] for k, v in obs.items()},
                    {**encode_info(info_row(info, i)), **labels},
                )
                for i in range(n)
            ]
            running = np.ones(n, dtype=bool)
            while running.any():
                chosen = checked_actions(policy(obs), space, rows)
                actions = chosen
                if executor is not None:
                    actions = checked_actions(executor(obs), space, rows, "executor")
                if scale is not None:
                    noise_now = np.stack([r.standard_normal(space.shape) for r in rngs])
                    drawn = actions + scale * noise_now
                    actions = np.clip(drawn, space.low, space.high).astype(space.dtype)
                obs, reward, terminated, truncated, info = envs.step(actions)
                for i in np.flatnonzero(running).tolist():
                    if labelled:
                        labels = {DEMONSTRATOR_ACTION: chosen[i]}
                    batch[i].add(
                        {k: v[i] for k, v in obs.items()},
                        actions[i],
                        reward[i],
                        terminated[i],
                        truncated[i],
                        {**encode_info(info_row(info, i)), **labels},
                    )
                running &= ~(terminated | truncated)
        finally:
            envs.close()
        out.extend(batch)
    return out


def record(
    dataset_id: str,
    env_id: str,
    policy: Callable[[dict], np.ndarray],
    episodes: int,
    seed: int = 0,
    env_kwargs: dict | None = None,
    num_envs: int = 50,
    algorithm_name: str | None = None,
    description: str | None = None,
    noise: float | Sequence[float] | None = None,
    executor: Callable[[dict], np.ndarray] | None = None,
):
    """Record ``episodes`` episodes of ``policy`` on ``env_id`` as the Minari dataset
    ``dataset_id``; returns the ``minari.MinariDataset``.

    Args:
        dataset_id: Minari's form, ``(namespace/)name-vN``; must not exist yet.
        env_id: any registered id; ``env_kwargs`` are merged over its arguments (JSON
            values only: the dataset stores the spec).
        policy: called with a batch of observations (a dict of (n, ...) arrays, one
            row per arm) and returns the (n, action dim) actions. If it has a
            ``reset(arms)`` method, that is called with the arms' indices before each
            batch's first step (a stateful controller, e.g. examples/scripted.py's).
        episodes: how many; episode k is seeded ``seed + k``.
        num_envs: arms run side by side (the last batch may be smaller).
        noise: the standard deviation (one, or one per action dimension, in the action
            space's units) of the Gaussian noise added to each action before it is
            executed; the policy's own action is stored as the info
            ``demonstrator_action`` (DART). None or 0: the policy's actions as they are.
        executor: another policy (called and reset as ``policy``) whose actions are
            executed (plus ``noise``) while ``policy`` labels each state it visits
            (``demonstrator_action``): DAgger's relabelled rollouts of a learner (Ross
            et al., 2011), the policy the demonstrator. None: ``policy`` acts.

    Raises ``ValueError`` (before anything is written) for a malformed or existing
    dataset id, an unknown env id, arguments that cannot be stored, a negative or
    misshapen noise, or an action outside the action space; a failure while writing
    removes what was written.
    """
    import mujoco
    from minari import create_dataset_from_buffers

    import franka_sim_gym

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if num_envs < 1:
        raise ValueError(f"num_envs must be >= 1, got {num_envs}")
    check_new_id(dataset_id)
    spec = dataset_spec(env_id, env_kwargs)
    recorded = run_episodes(spec, policy, episodes, seed, num_envs, noise, executor)
    envs = gym.make_vec(spec, num_envs=1, vectorization_mode="vector_entry_point")
    spaces = envs.single_observation_space, envs.single_action_space
    envs.close()
    path = dataset_path(dataset_id)
    try:
        with warnings.catch_warnings():
            # Minari asks for an author, e-mail and code link; a dataset needs none.
            warnings.filterwarnings("ignore", message=".*is set to None", category=UserWarning)
            return create_dataset_from_buffers(
                dataset_id,
                [episode.buffer(k) for k, episode in enumerate(recorded)],
                env=spec,
                eval_env=spec,
                algorithm_name=algorithm_name,
                description=description,
                observation_space=spaces[0],
                action_space=spaces[1],
                requirements=[
                    f"franka-sim-gym=={franka_sim_gym.__version__}",
                    # the physics' last bits, which the replay's bit-for-bit needs
                    f"mujoco=={mujoco.__version__}",
                ],
            )
    except BaseException:
        shutil.rmtree(path, ignore_errors=True)
        raise


def episode_seed(dataset, episode_id: int) -> int:
    """The seed episode ``episode_id`` of ``dataset`` was reset with (its metadata)."""
    (metadata,) = dataset.storage.get_episode_metadata([episode_id])
    return int(metadata["seed"])


def replay(dataset, episode) -> dict[str, Any]:
    """Run a stored episode again on the dataset's env: reset with its seed, step its
    actions. Returns what the env gave, laid out as the stored episode (``observations``
    (a dict of stacked arrays), ``rewards``, ``terminations``, ``truncations``)."""
    env = dataset.recover_environment()
    try:
        obs, _ = env.reset(seed=episode_seed(dataset, episode.id))
        observations = {key: [value] for key, value in obs.items()}
        rewards, terminations, truncations = [], [], []
        for action in episode.actions:
            obs, reward, terminated, truncated, _ = env.step(action)
            for key, value in obs.items():
                observations[key].append(value)
            rewards.append(reward)
            terminations.append(terminated)
            truncations.append(truncated)
    finally:
        env.close()
    return {
        "observations": {k: np.stack(v) for k, v in observations.items()},
        "rewards": np.asarray(rewards),
        "terminations": np.asarray(terminations),
        "truncations": np.asarray(truncations),
    }


def summary(dataset) -> tuple[float, float, Counter]:
    """The dataset's success rate (an episode's last ``is_success``, not after a reflex,
    as ``evaluation.evaluate`` judges), its reflex rate and the reflexes by error name."""
    successes = reflexes = 0
    reasons: Counter = Counter()
    for episode in dataset.iterate_episodes():
        if episode.terminations[-1]:
            reflexes += 1
            reasons.update(names(episode.infos["reflex_reason"][-1]))
        else:
            successes += bool(episode.infos["is_success"][-1])
    n = dataset.total_episodes
    return successes / n, reflexes / n, reasons
