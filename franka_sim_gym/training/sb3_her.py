"""stable-baselines3's HER replay buffer, keeping each transition's reflex charge.

    from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer
    model = SAC("MultiInputPolicy", env, replay_buffer_class=ReflexChargedHerReplayBuffer,
                replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"))

Why: a reflex ends an episode, and the env charges that step the worst reward of every
step the episode would still have had (``info["reflex_penalty"]``, docs/training.md), so a
reflex is never a shortcut to a higher return. ``compute_reward`` adds the charge from
the info it is given. SB3's ``HerReplayBuffer`` relabels most samples (4 of 5 here) and,
unless ``copy_info_dict=True``, hands ``compute_reward`` empty infos: a relabelled reflex
step then becomes a terminal transition whose goal is its own end point, reward 0, the
best value a transition can have. The learner is taught that tripping a reflex is a
success. ``copy_info_dict=True`` keeps the infos but deep-copies a batch of whole info
dicts at every gradient step.

This buffer keeps only what relabelling needs: the charge, one float per transition,
which ``compute_reward`` accepts in place of the infos (``Reach.compute_reward``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3 import HerReplayBuffer


class ReflexCharges:
    """The reflex charge of every stored transition, in the place of HER's info store.

    HER writes a step's infos with ``infos[pos] = [info of each arm]`` and reads a batch
    with ``infos[batch_indices, env_indices]``, which here is a float array (cheap for
    HER's deep copy; ``compute_reward`` takes it as the charges).
    """

    def __init__(self, buffer_size: int, n_envs: int) -> None:
        self.penalty = np.zeros((buffer_size, n_envs))

    def __setitem__(self, pos: int, infos: list[dict[str, Any]]) -> None:
        self.penalty[pos] = [info.get("reflex_penalty", 0.0) for info in infos]

    def __getitem__(self, index) -> np.ndarray:
        return self.penalty[index]


class ReflexChargedHerReplayBuffer(HerReplayBuffer):
    """``HerReplayBuffer`` whose relabelled transitions keep their reflex charge.

    Takes every argument of ``HerReplayBuffer`` except ``copy_info_dict``, which it
    replaces: the charge is stored as one float per transition (see the module's
    docstring for why relabelling needs it).
    """

    def __init__(self, *args, **kwargs) -> None:
        if kwargs.pop("copy_info_dict", False):
            raise ValueError(
                "ReflexChargedHerReplayBuffer keeps the reflex charge itself: "
                "copy_info_dict is not an option"
            )
        super().__init__(*args, copy_info_dict=False, **kwargs)
        # Set after SB3's constructor, which would otherwise fill an object array with an
        # empty dict per slot (a million of them at the default buffer size).
        self.copy_info_dict = True
        self.infos = ReflexCharges(self.buffer_size, self.n_envs)
