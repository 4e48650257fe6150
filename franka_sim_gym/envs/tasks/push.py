"""Push: a 4 cm block on the table pushed to a goal on the table, the fingers closed.

panda-gym's Push and Gymnasium-Robotics' FetchPush, on an FR3 whose collision reflexes
are live: a push hard enough to trip ``cartesian_reflex`` ends the episode and is
charged (docs/env.md, "Push").
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from .base import GoalDistanceTask
from .objects import object_space, object_state, on_table, place_object

#: The block's half size [m] (scenes/block.xml): its centre rests this high.
HALF = 0.02
#: The centre of the block and goal ranges on the table, in the base frame [m].
CENTRE = np.array([0.52, 0.0])
#: Half-width of the block's and the goal's ranges in x and y [m]: panda-gym's 0.3 m
#: squares (obj_xy_range, goal_xy_range).
RANGE = 0.15
#: Where episodes start: the TCP (the hand's, between the closed fingertips) 0.15 m
#: above the table at (0.50, 0, 0.15), the hand pointing down as at the home pose
#: (joint positions solved numerically; tests/envs/tasks/test_push.py checks the TCP),
#: so an episode is spent on the block, not on the 0.34 m descent from the home pose.
TABLE_HOME = np.array([0.0, 0.1513, 0.0, -2.398, 0.0, 2.5494, 0.7854])
TABLE_HOME.flags.writeable = False


class Push(GoalDistanceTask):
    """Push the block's centre within ``distance_threshold`` of a goal on the table.

    Args:
        reward_type: "sparse" (-1 per step until the block is within the threshold,
            else 0) or "dense" (minus the block's distance to the goal).
        distance_threshold: success radius [m] (default 5 cm, panda-gym's and Fetch's).
    """

    id_name = "Push"
    default_interface = "cartesian_velocity"
    interfaces = ("cartesian_velocity", "cartesian_pose", "joint_position", "joint_velocity")
    scene = "block"
    hand = "closed"
    home = TABLE_HOME
    max_episode_steps = 100
    cartesian_kwargs = {"cartesian_dof": 3}
    #: ``safety_box="task"``: the TCP no lower than 2.5 cm (the closed fingertips reach
    #: 1.2 cm below it: a hand pressed onto the table trips cartesian_reflex there),
    #: over the block's range and 3-5 cm beyond it (a push starts behind the block),
    #: not nearer the base than 0.33 m (the elbow nears its stop: fast twists there
    #: trip the IK's joint side) nor farther than 0.70 m or 0.20 m aside (the arm nears
    #: full stretch, the same). A policy pressing into the table and the walls with
    #: jitter trips nothing inside it (tests/envs/test_safety_box.py).
    safety_box = ((0.33, -0.20, 0.025), (0.70, 0.20, 0.25))
    #: the block's free joint in scenes/block.xml
    object_joint = "block"
    #: the observation bounds a position to 2 m per axis (objects.object_space)
    farthest_distance = float(np.sqrt(3) * 4.0)

    # -- episodes ------------------------------------------------------------------------------

    def sample_object(self, rng: np.random.Generator) -> np.ndarray:
        """The block's start on the table (its centre), drawn from ``rng``."""
        return np.append(rng.uniform(CENTRE - RANGE, CENTRE + RANGE), HALF)

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        return np.append(rng.uniform(CENTRE - RANGE, CENTRE + RANGE), HALF)

    def reset(self, arms, rngs, physics) -> np.ndarray:
        """The block at rest at a seeded spot, upright; then the goal (in that order)."""
        goals = []
        for i in arms.tolist():
            start = on_table(physics, i, self.sample_object(rngs[i]))
            place_object(physics, self.object_joint, i, start)
            goals.append(self.sample_goal(rngs[i]))
        return np.stack(goals)

    # -- observations --------------------------------------------------------------------------

    def extra_space(self) -> spaces.Box:
        return object_space()

    def observe(self, physics, ee):
        state = object_state(physics, self.object_joint)
        return state[:, :3], state
