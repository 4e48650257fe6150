"""The native batched vector env: N arms, each its own MuJoCo world, one controller call a cycle.

``gym.make_vec("FrankaFCI-v0", num_envs=N, vectorization_mode="vector_entry_point")``
(or any per-interface id) returns a :class:`FrankaFCIVectorEnv`. Arm i behaves
exactly like a single ``FrankaFCIEnv`` reset with seed ``seed + i`` and given the same
actions: same observations, rewards and infos (tests/envs/test_vector_env.py), because
both are the same batched core (envs/core.py), the single env with one arm.
"""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .core import FciBatch
from .infos import info_row


class FrankaFCIVectorEnv(VectorEnv):
    """N FrankaFCI episodes stepped together (Gymnasium 1.x ``VectorEnv``).

    Args:
        num_envs: the number of arms.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default, Gymnasium's) — the step
            after an arm's episode ended resets it, ignoring its action, and returns the
            reset observation with reward 0 — or ``AutoresetMode.SAME_STEP`` — the arm
            is reset in the step that ended it; ``info["final_obs"]`` and
            ``info["final_info"]`` then hold what the episode ended with.
        **kwargs: any argument of ``FrankaFCIEnv`` except the rendering ones; ``channel``
            may be a list with one channel model or spec per arm.

    A reflex on arm i ends arm i's episode only; the other arms run on undisturbed.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs,
    ) -> None:
        kwargs.pop("render_mode", None)  # not supported: N arms have no single camera
        kwargs.pop("width", None)
        kwargs.pop("height", None)
        if isinstance(autoreset_mode, str) and autoreset_mode.upper() in AutoresetMode.__members__:
            autoreset_mode = AutoresetMode[autoreset_mode.upper()]  # "same_step" also works
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        if self.autoreset_mode == AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode: NEXT_STEP or SAME_STEP (DISABLED is not supported)")
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.core = FciBatch(int(num_envs), **kwargs)
        self.num_envs = self.core.n
        self.single_action_space = self.core.action_space
        self.single_observation_space = self.core.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.render_mode = None
        #: each arm's random stream (a single env's np_random)
        self.rngs: list[np.random.Generator] = []
        self._autoreset = np.zeros(self.num_envs, dtype=bool)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Reset every arm (or those of ``options["reset_mask"]``); an int seed gives arm i
        the seed ``seed + i``, as Gymnasium's SyncVectorEnv does."""
        n = self.num_envs
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed: a list needs one seed per arm ({n}), got {len(seeds)}")
        mask = np.ones(n, dtype=bool)
        if options and "reset_mask" in options:
            mask = np.asarray(options["reset_mask"], dtype=bool)
            if mask.shape != (n,):
                raise ValueError(f"reset_mask must have shape ({n},), got {mask.shape}")
        if not self.rngs:
            self.rngs = [seeding.np_random(s)[0] for s in seeds]
        else:
            for i in np.flatnonzero(mask).tolist():
                if seeds[i] is not None:
                    self.rngs[i] = seeding.np_random(seeds[i])[0]
        arms = np.flatnonzero(mask)
        self.core.reset_arms(arms, self.rngs)
        self._autoreset[arms] = False
        obs, info = self.core.observe()
        return obs, _with_masks(info, mask)

    def step(self, actions):
        """One policy step of every arm (autoreset as ``autoreset_mode`` says)."""
        core = self.core
        waiting = self._autoreset
        if self.autoreset_mode == AutoresetMode.NEXT_STEP and waiting.any():
            actions = np.array(actions, dtype=np.float64)
            if actions.shape[:1] == waiting.shape:
                actions[waiting] = 0.0  # ignored: they may be anything, even NaN
            obs, reward, terminated, truncated, info = core.step(actions, ~waiting)
            arms = np.flatnonzero(waiting)
            core.reset_arms(arms, self.rngs)
            reset_obs, reset_info = core.observe()
            for key in obs:
                obs[key][arms] = reset_obs[key][arms]
            for key in info:
                info[key][arms] = reset_info[key][arms]
            reward[arms] = 0.0
            terminated = terminated & ~waiting
            truncated = truncated & ~waiting
        else:
            obs, reward, terminated, truncated, info = core.step(actions)
        done = terminated | truncated
        info = _with_masks(info, np.ones(self.num_envs, dtype=bool))
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            arms = np.flatnonzero(done)
            # final_obs and final_info laid out as Gymnasium's SyncVectorEnv lays them out
            # (its _add_info, which VectorEnv gives its subclasses).
            final: dict = {}
            for i in arms.tolist():
                row = {key: value[i].copy() for key, value in obs.items()}
                final = self._add_info(
                    final, {"final_obs": row, "final_info": info_row(info, i)}, i
                )
            core.reset_arms(arms, self.rngs)
            reset_obs, reset_info = core.observe()
            obs = {key: value.copy() for key, value in obs.items()}
            for key in obs:
                obs[key][arms] = reset_obs[key][arms]
            for key in reset_info:
                info[key][arms] = reset_info[key][arms]
            info.update(final)
            self._autoreset[...] = False
        else:
            self._autoreset = done.copy()
        return obs, reward, terminated, truncated, info

    def compute_reward(self, achieved_goal, desired_goal, info):
        """Vectorised reward (HER relabels goals with it)."""
        return self.core.task.compute_reward(achieved_goal, desired_goal, info)

    def close_extras(self, **kwargs) -> None:
        """Nothing to release: the world lives in this process."""


def _with_masks(info: dict, mask: np.ndarray) -> dict:
    """Gymnasium's vector info layout: every key has a boolean ``_key`` twin."""
    out = dict(info)
    for key in info:
        out[f"_{key}"] = mask.copy()
    return out
