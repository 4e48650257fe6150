"""stable-baselines3's ``VecEnv`` on the native batched env: N arms, one call, no subprocesses.

    from stable_baselines3 import SAC
    from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer
    from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv

    env = FrankaFCISB3VecEnv(16, action_interface="joint_position")
    model = SAC("MultiInputPolicy", env, replay_buffer_class=ReflexChargedHerReplayBuffer)

SB3 resets an ended episode in the step that ended it (its VecEnv contract): the
adapter runs the vector env in ``SAME_STEP`` autoreset mode and hands SB3 the
episode's last observation as ``info["terminal_observation"]`` and
``info["TimeLimit.truncated"]``, as its DummyVecEnv does. HER reaches the
vectorised ``compute_reward`` through ``env_method``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from franka_sim_gym.envs.infos import info_row
from franka_sim_gym.envs.vector_env import FrankaFCIVectorEnv


class FrankaFCISB3VecEnv(VecEnv):
    """N FrankaFCI arms as one SB3 ``VecEnv``.

    Args:
        num_envs: the number of arms.
        **env_kwargs: any argument of ``FrankaFCIEnv`` (as for ``FrankaFCIVectorEnv``).
    """

    def __init__(self, num_envs: int, **env_kwargs) -> None:
        self.vector_env = FrankaFCIVectorEnv(
            num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs
        )
        venv = self.vector_env
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self):
        """Reset every arm (with the seeds given to ``seed()``, if any)."""
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        obs, info = self.vector_env.reset(seed=seeds)
        self.reset_infos = [info_row(info, i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.vector_env.step(self._actions)
        done = terminated | truncated
        infos = []
        for i in range(self.num_envs):
            if done[i]:
                row = info_row(info["final_info"], i)  # a vector info, as SyncVectorEnv's
                row["terminal_observation"] = info["final_obs"][i]
                row["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                self.reset_infos[i] = info_row(info, i)
            else:
                row = info_row(info, i)
                row["TimeLimit.truncated"] = False
            infos.append(row)
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        self.vector_env.close()

    def compute_reward(self, achieved_goal, desired_goal, info) -> np.ndarray:
        """Vectorised reward (HER calls it through ``env_method``)."""
        return self.vector_env.compute_reward(achieved_goal, desired_goal, info)

    # -- the VecEnv attribute protocol: every arm shares one env object ------------------------

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        target = self._target(attr_name)
        return [getattr(target, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self._target(attr_name), attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        method = getattr(self._target(method_name), method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def _target(self, name: str):
        """Where an attribute lives: the vector env, else its batched core."""
        venv = self.vector_env
        return venv if hasattr(venv, name) else venv.core
