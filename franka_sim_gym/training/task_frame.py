"""A manipulation policy's inputs in the task's frame: where the object is from the hand,
where the goal is from the object.

    from franka_sim_gym.training.task_frame import TaskFrame, frame_statistics
    mean, std = frame_statistics(dataset, rotation=False)
    policy_kwargs = dict(features_extractor_class=TaskFrame,
                         features_extractor_kwargs=dict(rotation=False, mean=mean, std=std))

The env's observation (docs/env.md, "Manipulation tasks") gives the joint state and every
position in the robot's base frame, as the robot reports them. A policy fitted to 50
demonstrations from those 36-37 numbers must find out for itself that only differences
matter: the block 1 cm to the left of the hand calls for the same motion wherever on the
table the two are. ``TaskFrame`` hands it the differences (the object from the TCP, the
goal from the object), the TCP's height above the table, the commanded velocity, the
hand's width (PickAndPlace), and the object's velocity; with ``rotation`` (a 6-D twist:
PegInsertion) also the object's orientation and angular velocity and the commanded
angular velocity. Nothing of the joint state: the joint-space reflexes are left to the
robot's own limits and to the demonstrations; with ``elbow``, joint 4's angle (how far the
elbow has folded toward its stop, where the solvers slow near the base:
``line_frame``). Measured on Push, behaviour cloning from
the same 50 noise-injected demonstrations, seeds 0-2: 0.07-0.17 success from the
base-frame observation, 0.71-0.75 from the task frame (docs/demonstrations.md).

The features are normalised with fixed statistics (``frame_statistics`` of the
demonstrations), inside the network: HER relabels ``desired_goal`` with raw positions,
and the differences must be taken before any per-entry scaling. Train without SB3's
``VecNormalize``.

An SB3 ``BaseFeaturesExtractor``: ``policy_kwargs`` of SAC / TD3 / PPO's
``MultiInputPolicy``; a saved model loads with this module importable.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from franka_sim_gym.envs.commands import CARTESIAN
from franka_sim_gym.envs.tasks.objects import OBJECT_ENTRIES
from franka_sim_gym.training.governor import JOINT_4

#: the observation's layout (docs/env.md): q 0:7, dq 7:14, TCP position 14:17, the
#: commanded twist 17:23 (linear, angular), [the hand's width], then the object's 13:
#: position, quaternion w, x, y, z, linear velocity, angular velocity.
TCP = slice(14, 17)
TWIST_AT = 17
#: the first entry after the twist (linear and angular): the width, or the object
AFTER_TWIST = TWIST_AT + 6
#: the shortest observation with an object (no width): the twist, then the object
WITH_OBJECT = AFTER_TWIST + OBJECT_ENTRIES
#: a feature's smallest standard deviation [m, m/s, rad/s]: a feature that hardly varies
#: over the demonstrations (a block at rest between pushes, a peg held square) is
#: divided by at least this, so that a millimetre off what was demonstrated is one unit,
#: not thousands
MIN_STD = 1e-3


def frame_size(observation_dim: int, rotation: bool, elbow: bool = False) -> int:
    """How many features ``TaskFrame`` makes of an observation of ``observation_dim``."""
    if observation_dim < WITH_OBJECT:
        raise ValueError(
            f"TaskFrame needs a task with an object (an observation of >= "
            f"{WITH_OBJECT} entries: docs/env.md); this one has "
            f"{observation_dim}: use the base-frame observation (no features extractor)"
        )
    zeros = th.zeros(1, observation_dim)
    return frame_features(zeros, th.zeros(1, 3), rotation, elbow).shape[1]


def frame_features(
    observation: th.Tensor, goal: th.Tensor, rotation: bool, elbow: bool = False
) -> th.Tensor:
    """(n, frame_size) the task-frame features of a batch of observations and goals;
    with ``elbow``, joint 4's angle last."""
    object_at = observation.shape[1] - OBJECT_ENTRIES
    tcp = observation[:, TCP]
    obj = observation[:, object_at : object_at + 3]
    twist = observation[:, TWIST_AT : TWIST_AT + (6 if rotation else 3)]
    extra = observation[:, AFTER_TWIST:object_at]  # the hand's width, where there is one
    parts = [obj - tcp, goal - obj, tcp[:, 2:3], twist, extra]
    if rotation:  # quaternion, then linear and angular velocity
        parts.append(observation[:, object_at + 3 : object_at + OBJECT_ENTRIES])
    else:  # the linear velocity only
        parts.append(observation[:, object_at + 7 : object_at + 10])
    if elbow:  # how far the elbow has folded toward its stop (training/governor.py)
        parts.append(observation[:, JOINT_4 : JOINT_4 + 1])
    return th.cat(parts, dim=1)


class TaskFrame(BaseFeaturesExtractor):
    """The task-frame features of a goal-conditioned Dict observation, normalised with
    fixed statistics (``mean``, ``std``: lists of ``frame_size`` numbers; none: raw);
    ``elbow``: joint 4's angle too."""

    def __init__(
        self,
        observation_space: gym.spaces.Dict,
        rotation: bool = False,
        mean: Any = None,
        std: Any = None,
        elbow: bool = False,
    ) -> None:
        size = frame_size(observation_space["observation"].shape[0], rotation, elbow)
        super().__init__(observation_space, features_dim=size)
        self.rotation, self.elbow = rotation, elbow
        for name, value, default in (("mean", mean, 0.0), ("std", std, 1.0)):
            tensor = th.full((size,), default) if value is None else th.as_tensor(value)
            if tensor.shape != (size,):
                raise ValueError(f"{name} has {tensor.numel()} entries, expected {size}")
            self.register_buffer(name, tensor.to(th.float32))
        if not bool((self.std > 0).all()):
            raise ValueError("std must be > 0 everywhere")

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        features = frame_features(
            observations["observation"], observations["desired_goal"], self.rotation, self.elbow
        )
        return (features - self.mean) / self.std


def frame_statistics(
    dataset: Any,
    rotation: bool,
    prepare: Callable[[dict], dict] | None = None,
    elbow: bool = False,
) -> tuple[list[float], list[float]]:
    """The mean and standard deviation of the task-frame features over every recorded
    observation of a Minari dataset (or its id): ``TaskFrame``'s ``mean`` and ``std``.
    ``prepare`` turns each episode's observations first (the line's frame:
    ``line_frame.line_observations``)."""
    from franka_sim_gym.training.sb3_demos import load

    rows = []
    for episode in load(dataset).iterate_episodes():
        obs = episode.observations if prepare is None else prepare(episode.observations)
        rows.append(
            frame_features(
                th.as_tensor(obs["observation"], dtype=th.float64),
                th.as_tensor(obs["desired_goal"], dtype=th.float64),
                rotation,
                elbow,
            )
        )
    features = th.cat(rows).numpy()
    std = np.maximum(features.std(axis=0), MIN_STD)
    return features.mean(axis=0).tolist(), std.tolist()


def has_object(observation_space: gym.spaces.Dict) -> bool:
    """Whether the env's observation ends with an object's 13 entries (Push,
    PickAndPlace, PegInsertion)."""
    return observation_space["observation"].shape[0] >= WITH_OBJECT


def frame_rotation(observation_space: gym.spaces.Dict, env_kwargs: dict) -> bool | None:
    """How ``TaskFrame`` applies to an env of these arguments (its spec's kwargs): None
    where it does not (no object, or a joint or torque interface, whose policy needs the
    joint state the task frame leaves out); else whether the action turns the hand (a
    Cartesian interface with ``cartesian_dof`` 6, PegInsertion's default), so that the
    object's orientation and angular velocity are among the features."""
    if not has_object(observation_space) or env_kwargs.get("action_interface") not in CARTESIAN:
        return None
    return int(env_kwargs.get("cartesian_dof", 6)) == 6


def frame_kwargs(
    dataset: Any,
    env_kwargs: dict,
    observation_space: gym.spaces.Dict,
    prepare: Callable[[dict], dict] | None = None,
    elbow: bool = False,
) -> dict:
    """SB3 ``policy_kwargs`` entries that put ``TaskFrame`` in front of a policy's
    networks, with the dataset's statistics (of its observations after ``prepare``, if
    given: ``frame_statistics``), joint 4's angle among the features with ``elbow``; a
    ``ValueError`` naming why where the task frame does not apply."""
    rotation = frame_rotation(observation_space, env_kwargs)
    if rotation is None:
        raise ValueError(
            "the task frame needs a task with an object and a Cartesian action interface "
            f"(cartesian_velocity, cartesian_pose); this env has action_interface="
            f"{env_kwargs.get('action_interface')!r} and an observation of "
            f"{observation_space['observation'].shape[0]} entries: use the base-frame "
            "observation (--features raw)"
        )
    mean, std = frame_statistics(dataset, rotation, prepare, elbow)
    extractor = dict(rotation=rotation, mean=mean, std=std)
    if elbow:  # (only then: the models saved before the flag load as they were)
        extractor["elbow"] = True
    return dict(features_extractor_class=TaskFrame, features_extractor_kwargs=extractor)
