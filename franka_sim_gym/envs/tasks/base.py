"""The task protocol: what a goal-conditioned task gives the batched core (envs/core.py).

A task is one small class in one file of ``envs/tasks/`` and one line in ``TASKS``
(``envs/tasks/__init__.py``). The core owns the robot (the FCI controller, the client,
the channel, the reflexes and their charge); a task owns what the episode is about:

* its goals, drawn at reset from the random stream the core hands it (one
  ``np.random.Generator`` per arm, the env's ``np_random``: never a global stream);
* the objects it places in the scene at reset (``reset`` receives the world's
  ``ArmPhysics``; a task with objects of its own declares their MJCF in ``scene``);
* what it adds to the observation (``extra_space`` and ``observe``) and what its
  achieved goal is (the end effector for Reach, an object's position for Push);
* its reward, vectorised for HER (``compute_reward``), its success (``is_success``) and
  the worst reward one step can give (``worst_step_reward``), which the core charges for
  every step a reflex cut off.

Every method is batched over the arms of the world: arrays carry a leading arm axis,
as everywhere in the core (docs/architecture.md, "Batch first").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces


class Task(ABC):
    """A goal-conditioned task on n arms (see the module docstring).

    Class attributes name the task's Gymnasium ids (``envs/__init__.py`` registers them):
    ``FrankaFCI{id_name}-v0`` with ``default_interface``, and
    ``FrankaFCI{id_name}{Interface}-v0`` for each of ``interfaces``.
    """

    #: the ids' infix ("" for Reach: FrankaFCI-v0, FrankaFCIJointPosition-v0, ...)
    id_name: ClassVar[str] = ""
    #: the action interface of ``FrankaFCI{id_name}-v0``
    default_interface: ClassVar[str] = "joint_position"
    #: the interfaces the task is registered for, one id each (None: every one)
    interfaces: ClassVar[tuple[str, ...] | None] = None
    #: The scene fragment of the objects the task places per arm: a shipped name
    #: (sim/scene.py SCENES) or an MJCF file; the world builder attaches one copy per
    #: arm, in the arm's base frame (None: the bare table).
    scene: ClassVar[str | None] = None
    #: the length of the achieved and desired goals
    goal_dim: ClassVar[int] = 3
    #: The Franka Hand the task needs: None (the env's ``gripper`` argument decides),
    #: "grasp" (mounted, its width the last action, on the force-limited finger servo),
    #: "closed" (mounted, fingers squeezed shut, no width action) or "held" (mounted,
    #: squeezing what the task's ``reset`` put between the fingers, no width action).
    hand: ClassVar[str | None] = None
    #: The joint positions episodes start around (None: the robot's home pose).
    home: ClassVar[np.ndarray | None] = None
    #: The episode length of the task's ids (2 s at 25 Hz for Reach).
    max_episode_steps: ClassVar[int] = 50
    #: Arguments the task's Cartesian ids carry (e.g. ``{"cartesian_dof": 3}``).
    cartesian_kwargs: ClassVar[dict] = {}
    #: The free joint of the object the hand may hold (a name in the task's scene): while
    #: both fingertips touch it, its mass is the robot's configured load
    #: (``configure_load``). None: nothing to hold.
    held_object: ClassVar[str | None] = None
    #: The TCP's workspace box of ``safety_box="task"``: ((x, y, z) lowest, (x, y, z)
    #: highest) in the base frame [m] (envs/commands.py; None: the task has none).
    safety_box: ClassVar[tuple[tuple[float, ...], tuple[float, ...]] | None] = None

    # -- episodes ------------------------------------------------------------------------------

    @abstractmethod
    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        """One arm's goal, (goal_dim,), drawn from ``rng``."""

    def reset(self, arms: np.ndarray, rngs: list, physics: Any) -> np.ndarray:
        """New episodes on ``arms``: place the task's objects and draw the goals, arm i
        from ``rngs[i]`` after the core drew its start pose. Returns (len(arms), goal_dim).

        The default draws ``sample_goal`` per arm (a task without objects)."""
        return np.stack([self.sample_goal(rngs[i]) for i in arms.tolist()])

    # -- observations --------------------------------------------------------------------------

    def extra_space(self) -> spaces.Box | None:
        """The bounds of the entries the task appends to ``observation`` (None: none)."""
        return None

    def observe(self, physics: Any, ee: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The achieved goals (n, goal_dim) and the observation's extra entries (n, k) or
        None, of every arm as the world stands; ``ee`` is (n, 3) O_T_EE's position.

        The default: the end effector is the achieved goal, no extras."""
        return ee, None

    # -- rewards -------------------------------------------------------------------------------

    @abstractmethod
    def compute_reward(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """float32 rewards, vectorised over a leading batch axis (HER calls it so).

        ``info`` is one step's info, a sequence of them, or a numeric array of their
        ``reflex_penalty`` values; add ``reflex_penalty(info)`` to the reward so that a
        relabelled reflex step stays charged."""

    @abstractmethod
    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        """Booleans, vectorised like ``compute_reward``."""

    @property
    @abstractmethod
    def worst_step_reward(self) -> float:
        """The lowest reward one step can give: the core charges it for every step a
        reflex cut off (info["reflex_penalty"])."""


def reflex_penalty(info) -> np.ndarray | None:
    """The ``reflex_penalty`` of one info dict, of a sequence of them, or the penalties
    themselves as a numeric array (None: no infos, no charge)."""
    if info is None:
        return None
    if isinstance(info, dict):
        return np.asarray(info.get("reflex_penalty", 0.0), dtype=np.float64)
    if isinstance(info, np.ndarray) and info.dtype.kind in "fiu":
        return info.astype(np.float64)
    rows = list(info)
    if not rows or not isinstance(rows[0], dict):
        return None
    return np.array([row.get("reflex_penalty", 0.0) for row in rows], dtype=np.float64)


def charged(reward: np.ndarray, info) -> np.ndarray:
    """``reward`` (float32) plus the reflex charge the infos carry."""
    penalty = reflex_penalty(info)
    if penalty is None:
        return reward
    return (reward + np.reshape(penalty, np.shape(reward))).astype(np.float32)


def goal_distance(achieved_goal, desired_goal) -> np.ndarray:
    """Euclidean distances over the last axis (vectorised over leading batch axes)."""
    return np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)


class GoalDistanceTask(Task):
    """A task scored by the distance from the achieved to the desired goal: the reward
    rule of Reach, Push, PickAndPlace and PegInsertion (panda-gym's and Fetch's).

    Args:
        reward_type: "sparse" (-1 per step until within the threshold, else 0) or
            "dense" (minus the distance to the goal).
        distance_threshold: success radius [m].
    """

    #: The farthest an achieved goal can be from a desired one [m]: minus it is the
    #: dense reward's worst step.
    farthest_distance: ClassVar[float]

    def __init__(self, reward_type: str = "sparse", distance_threshold: float = 0.05) -> None:
        if reward_type not in ("sparse", "dense"):
            raise ValueError(f"reward_type must be 'sparse' or 'dense', got {reward_type!r}")
        if not distance_threshold > 0:
            raise ValueError(f"distance_threshold must be > 0, got {distance_threshold!r}")
        self.reward_type = reward_type
        self.distance_threshold = float(distance_threshold)

    def __repr__(self) -> str:
        name, threshold = type(self).__name__, self.distance_threshold
        return f"{name}(reward_type={self.reward_type!r}, distance_threshold={threshold})"

    def compute_reward(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """Vectorised over a leading batch axis, as SB3's HER calls it.

        ``info`` is one step's info dict, a sequence of them (HER passes the stored
        ones), or a numeric array of their ``reflex_penalty`` values (what the training
        package's HER buffer stores). The charge is added, so a step's own transition
        gives the step's reward and a relabelled reflex step stays charged.
        """
        d = goal_distance(achieved_goal, desired_goal)
        if self.reward_type == "sparse":
            reward = -(d > self.distance_threshold).astype(np.float32)
        else:
            reward = -d.astype(np.float32)
        return charged(reward, info)

    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        return goal_distance(achieved_goal, desired_goal) <= self.distance_threshold

    @property
    def worst_step_reward(self) -> float:
        """-1 (sparse), or minus ``farthest_distance`` (dense)."""
        if self.reward_type == "sparse":
            return -1.0
        return -self.farthest_distance
