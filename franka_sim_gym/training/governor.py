"""A Cartesian-velocity policy slowed toward the base as the FR3's elbow nears its stop.

Moving the hand toward the base folds the elbow: joint 4 runs toward its lower limit
(fci/tables.py, the FR3's ``q_lower``: -3.0481 rad), and near it the robot's IK of a Cartesian
velocity asks for joint speeds and accelerations its motion generator refuses
(``cartesian_motion_generator_joint_velocity_limits_violation``,
``..._joint_acceleration_discontinuity``). The scripted solvers slow down there on the
TCP's base-frame position, which a clone on the translation-free task frame cannot see
(docs/demonstrations.md, "Push: the closest it comes"). ``ElbowGovernor`` is the rule a
robot programmer would put after a learnt policy: the action's velocity toward the base
(its first entry negative) is capped by a cap that falls linearly from the whole range
at ``slow_from`` to ``floor`` at ``stop_at`` (joint 4's angle, the observation's entry
3: docs/env.md), everything else passed through. On Push it took out the IK's reflexes
(docs/demonstrations.md, "The elbow governor").
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: joint 4's entry in the observation (q 0:7, docs/env.md)
JOINT_4 = 3
#: joint 4's angles [rad] at which the governor starts slowing motion toward the base
#: and where it holds it at ``floor`` (measured on Push: at -2.83 to -2.96 rad the clones'
#: IK reflexes came, moving toward the base at 0.11-0.25 m/s; fci/tables.py's FR3 q_lower
#: -3.0481 rad is the stop)
SLOW_FROM, STOP_AT = -2.6, -2.85
#: the cap beyond STOP_AT, in action units (0.06 m/s): on Push's six five-clone fits,
#: 0.2 gave success 0.86-0.95 against 0.83-0.92 with 0 and the same median reflex rate
#: (docs/demonstrations.md, "The elbow governor")
FLOOR = 0.2


class ElbowGovernor:
    """``policy`` (SB3's ``predict`` over a batch; Cartesian velocity actions, the TCP's x
    velocity first) with its velocity toward the base capped as joint 4 nears its stop.

    Args:
        policy: anything with SB3's ``predict``.
        slow_from, stop_at: joint 4's angles [rad] between which the cap falls from 1
            (the action space's bound) to ``floor``; ``stop_at < slow_from``.
        floor: the cap at and beyond ``stop_at``, in action units (0: no motion toward
            the base there). The FR3's joint 4 (the defaults are its angles; the FER's
            stop, -3.0718 rad, is 0.024 rad further: fci/tables.py).
    """

    def __init__(
        self,
        policy: Any,
        slow_from: float = SLOW_FROM,
        stop_at: float = STOP_AT,
        floor: float = FLOOR,
    ) -> None:
        if not stop_at < slow_from:
            raise ValueError(f"stop_at ({stop_at}) must be below slow_from ({slow_from})")
        if not 0.0 <= floor <= 1.0:
            raise ValueError(f"floor must be in [0, 1] (action units), got {floor}")
        self.policy, self.floor = policy, float(floor)
        self.slow_from, self.stop_at = float(slow_from), float(stop_at)

    def cap(self, q4: np.ndarray) -> np.ndarray:
        """The largest speed toward the base (action units) at joint 4's angles ``q4``."""
        return np.interp(q4, [self.stop_at, self.slow_from], [self.floor, 1.0])

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The policy's actions, their velocity toward the base capped."""
        actions, state = self.policy.predict(observation, deterministic=deterministic)
        q4 = np.asarray(observation["observation"])[..., JOINT_4]
        governed = np.array(actions, copy=True)  # (the policy's dtype kept)
        governed[..., 0] = np.maximum(governed[..., 0], -self.cap(q4))
        return governed, state
