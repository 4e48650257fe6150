"""An object task's policy acting in the line's frame: the horizontal axes turned about
the vertical so that x points from the object to its goal.

Push's scripted solver (examples/scripted.py) decides by where the hand is along and off
the line from the block to its goal; turned with that line, its action is the same
whichever way the line points across the table. A network fitted to 50 demonstrations
in the base frame (even translation-free, on the task frame: ``task_frame``) has to
learn that symmetry from 50 directions, and blurs the solver's boundaries between them;
in the line's frame every demonstration is the same push, lined up the same way
(docs/demonstrations.md, "Push in the line's frame", has what it gives).

The frame turns the positions, velocities and orientation of the observation (the TCP,
the commanded twist, the object, the goals: the layout of docs/env.md) and the
Cartesian-velocity action's linear and angular velocity, by the angle of the line at
that step; the joint state is left as it is, and so is the object's angular velocity,
which is in the object's own axes (envs/tasks/objects.py). Heights are unchanged.
Measured on Push only (docs/demonstrations.md); on PegInsertion, whose hole is fixed in
the base frame, the line's frame is not a symmetry of the task and is unmeasured. The turned frame
no longer says where on the table the hand is, which the solvers act on near the base
(they slow down there, where the elbow folds toward its stop): ``train_bc.py --features
line`` gives the network joint 4's angle as well (``task_frame.TaskFrame``'s ``elbow``),
the fold itself, which is the same in any frame. ``LineFrame`` wraps
a policy fitted in the frame so that it acts on the env's observations;
``to_line_frame`` turns a dataset's observations and actions for the fitting. Where the
object is on its goal (closer than ``DEGENERATE`` across) the line has no direction and
the base frame's x is taken.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from franka_sim_gym.envs.tasks.objects import OBJECT_ENTRIES

#: horizontal distance [m] from the object to its goal under which the line has no
#: direction: a guard against dividing by zero (the base frame's x is used there), far
#: below any distance a task tells apart (Push succeeds at 5 cm: envs/tasks/push.py)
DEGENERATE = 1e-6
#: the observation's horizontal (x, y) pairs of base-frame vectors, as offsets: the TCP
#: position (14), the commanded twist's linear (17) and angular (20) velocity
#: (docs/env.md); and of the object (its last 13 entries): position (0) and linear
#: velocity (7). Its angular velocity (10) is in its own axes: a turn of the base frame
#: leaves it as it is.
OBSERVATION_PAIRS = (14, 17, 20)
OBJECT_PAIRS = (0, 7)
#: the object's quaternion (w, x, y, z) offset in its 13 entries
QUATERNION = 3
#: the goals' keys (positions, x and y first)
GOALS = ("desired_goal", "achieved_goal")


def line_turn(observation: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """(n, 2): the cosine and sine of the horizontal line from each row's object to its
    goal, measured from the base frame's x; (1, 0) where the two coincide across."""
    at = observation.shape[-1] - OBJECT_ENTRIES
    obj = np.asarray(observation, np.float64)[..., at : at + 2]
    d = np.asarray(goal, np.float64)[..., :2] - obj
    length = np.hypot(d[..., 0], d[..., 1])
    flat = length < DEGENERATE
    return np.where(flat[..., None], [1.0, 0.0], d / np.where(flat, 1.0, length)[..., None])


def _turn_pairs(values: np.ndarray, offsets, turn: np.ndarray, sign: float) -> None:
    """Turn ``values[..., k:k+2]`` for each offset k in place, by the angle of ``turn``
    (its cosine and sine) times ``sign`` (-1: into the line's frame, +1: back)."""
    c, s = turn[..., 0], sign * turn[..., 1]
    for k in offsets:
        x, y = values[..., k].copy(), values[..., k + 1].copy()
        values[..., k] = c * x - s * y
        values[..., k + 1] = s * x + c * y


def _turn_observation(obs: dict, turn: np.ndarray, sign: float) -> dict:
    """A copy of ``obs`` (a Dict observation, one row or a batch) turned about the
    vertical by ``sign`` times the angle of ``turn``, in float64."""
    o = np.array(obs["observation"], dtype=np.float64)
    at = o.shape[-1] - OBJECT_ENTRIES
    _turn_pairs(o, OBSERVATION_PAIRS, turn, sign)
    _turn_pairs(o, [at + k for k in OBJECT_PAIRS], turn, sign)
    # the object's orientation: the turn's quaternion (about z, half the angle) times it
    half = 0.5 * sign * np.arctan2(turn[..., 1], turn[..., 0])
    zw, zz = np.cos(half), np.sin(half)
    w, x, y, z = (o[..., at + QUATERNION + k].copy() for k in range(4))
    o[..., at + QUATERNION] = zw * w - zz * z
    o[..., at + QUATERNION + 1] = zw * x - zz * y
    o[..., at + QUATERNION + 2] = zw * y + zz * x
    o[..., at + QUATERNION + 3] = zw * z + zz * w
    # w >= 0, as the env reports it (envs/tasks/objects.py): q and -q are one orientation
    q = o[..., at + QUATERNION : at + QUATERNION + 4]
    q *= np.where(q[..., :1] < 0, -1.0, 1.0)
    turned = dict(obs)
    turned["observation"] = o
    for key in GOALS:
        if key in obs:
            g = np.array(obs[key], dtype=np.float64)
            _turn_pairs(g, (0,), turn, sign)
            turned[key] = g
    return turned


def _action_pairs(actions: np.ndarray) -> tuple[int, ...]:
    """The (x, y) pairs of a Cartesian-velocity action: the linear velocity's, and the
    angular velocity's in a 6-entry twist (a width, PickAndPlace's, after them)."""
    return (0, 3) if actions.shape[-1] in (6, 7) else (0,)


def turn_actions(actions: np.ndarray, turn: np.ndarray, sign: float) -> np.ndarray:
    """Cartesian-velocity actions turned by ``sign`` times the angle of ``turn``, in
    float64 (a turned corner of the action box is outside it)."""
    turned = np.array(actions, dtype=np.float64)
    _turn_pairs(turned, _action_pairs(turned), turn, sign)
    return turned


def to_line_frame(obs: dict, actions: np.ndarray | None = None) -> tuple[dict, Any]:
    """The observations (and actions, if given) of a batch in each row's line frame, in
    float64; the actions are None if not given: ``sb3_demos.behaviour_cloning``'s
    ``prepare``. A ``ValueError`` if a turned action leaves the action space's [-1, 1]
    (a label the actor cannot reach; clipping it would change its direction)."""
    turn = line_turn(obs["observation"], obs["desired_goal"])
    turned = _turn_observation(obs, turn, -1.0)
    if actions is None:
        return turned, None
    turned_actions = turn_actions(actions, turn, -1.0)
    outside = np.count_nonzero(np.abs(turned_actions).max(axis=-1) > 1.0)
    if outside:
        raise ValueError(
            f"{outside} of {len(turned_actions)} actions leave [-1, 1] in the line's frame "
            "(a horizontal speed above 1 on the diagonal): they cannot be fitted there"
        )
    return turned, turned_actions


def line_observations(obs: dict) -> dict:
    """The observations alone in the line's frame (the task frame's statistics:
    ``task_frame.frame_statistics``'s ``prepare``)."""
    return to_line_frame(obs)[0]


class LineFrame:
    """``policy`` (SB3's ``predict``; fitted on line-frame observations) acting on the
    env's: each observation turned into its line's frame, the action turned back."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The policy's action for the turned observation, turned back and clipped to
        the action space's [-1, 1], in its dtype."""
        turn = line_turn(observation["observation"], observation["desired_goal"])
        turned = _turn_observation(observation, turn, -1.0)
        typed = {k: v.astype(np.asarray(observation[k]).dtype) for k, v in turned.items()}
        actions, state = self.policy.predict(typed, deterministic=deterministic)
        back = np.clip(turn_actions(actions, turn, +1.0), -1.0, 1.0)
        return back.astype(np.asarray(actions).dtype, copy=False), state
