"""The observation: its space, and how it is built from a robot state.

One implementation for every way in: the single env, the batched vector env
(both through envs/core.py) and the deploy script
(examples/deploy_pylibfranka.py, which builds it from pylibfranka's RobotState),
so a policy sees the same numbers in training and on the robot.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ..fci.tables import RobotTable
from ..sim.gripper import MAX_WIDTH

#: Bound of every Cartesian coordinate [m]: the FR3 reaches ~0.9 m; EE frames may add.
CARTESIAN_BOUND = 2.0
#: Bound of every measured joint speed [rad/s]: physics keeps them far below.
JOINT_SPEED_BOUND = 20.0
#: Bound of every commanded twist component [m/s, rad/s]: the robot refuses more than
#: 3 m/s and 2.5 rad/s (cartesian_motion_generator_velocity_limits_violation).
TWIST_BOUND = 3.0


def observation_space(
    table: RobotTable,
    gripper: bool = False,
    extra: spaces.Box | None = None,
    goal_dim: int = 3,
) -> spaces.Dict:
    """Dict(observation, achieved_goal, desired_goal), float32, with honest bounds.

    ``observation`` = measured q (7), dq (7), O_T_EE position (3), the commanded twist
    O_dP_EE_c (6) [, hand width (1)] [, the task's extra entries (``extra``'s bounds)].
    The goals have ``goal_dim`` Cartesian coordinates.
    """
    q_lo = (table.q_lower - 0.2).astype(np.float32)
    q_hi = (table.q_upper + 0.2).astype(np.float32)
    dq_hi = np.full(7, JOINT_SPEED_BOUND, dtype=np.float32)
    box = np.full(3, CARTESIAN_BOUND, dtype=np.float32)
    twist = np.full(6, TWIST_BOUND, dtype=np.float32)
    width_lo, width_hi = ([0.0], [MAX_WIDTH]) if gripper else ([], [])
    extra_lo, extra_hi = ([], []) if extra is None else (extra.low.ravel(), extra.high.ravel())
    goal = np.full(goal_dim, CARTESIAN_BOUND, dtype=np.float32)
    return spaces.Dict(
        {
            "observation": spaces.Box(
                np.concatenate([q_lo, -dq_hi, -box, -twist, width_lo, extra_lo]).astype(np.float32),
                np.concatenate([q_hi, dq_hi, box, twist, width_hi, extra_hi]).astype(np.float32),
                dtype=np.float32,
            ),
            "achieved_goal": spaces.Box(-goal, goal, dtype=np.float32),
            "desired_goal": spaces.Box(-goal, goal, dtype=np.float32),
        }
    )


def build_observation(
    space: spaces.Dict,
    q: np.ndarray,
    dq: np.ndarray,
    ee: np.ndarray,
    goal: np.ndarray,
    twist: np.ndarray,
    width: np.ndarray | None = None,
    achieved: np.ndarray | None = None,
    extra: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """The observations of n robots, each array with a leading robot axis.

    Args:
        space: the single-robot ``observation_space`` (its bounds clip the values).
        q, dq: (n, 7) measured joint positions and velocities (RobotState q, dq).
        ee: (n, 3) O_T_EE position in the base frame (O_T_EE[12:15]).
        goal: (n, 3) the goals.
        twist: (n, 6) the commanded twist the robot reports (RobotState O_dP_EE_c): under
            the Cartesian interfaces the reference libfranka's filters start from, and
            so the state of the motion a policy steers (zero under the others).
        width: (n,) measured hand opening [m], when a hand is mounted.
        achieved: (n, goal_dim) the task's achieved goals (None: ``ee``, as for Reach).
        extra: (n, k) the task's extra entries (None: none).
    """
    parts = [q, dq, ee, twist]
    if width is not None:
        parts.append(np.reshape(width, (-1, 1)))
    if extra is not None:
        parts.append(np.reshape(extra, (len(q), -1)))
    obs = np.concatenate(parts, axis=1).astype(np.float32)
    box = space["observation"]
    np.clip(obs, box.low, box.high, out=obs)  # the bounds are the bounds
    return {
        "observation": obs,
        "achieved_goal": np.clip(
            ee if achieved is None else achieved, -CARTESIAN_BOUND, CARTESIAN_BOUND
        ).astype(np.float32),
        "desired_goal": np.asarray(goal).astype(np.float32),
    }
