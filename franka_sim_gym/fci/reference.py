"""The commanded joint signal and its backward-Euler history (q_d, dq_d, ddq_d).

One module owns the differencing history that the motion-limit checks and
the lost-cycle extrapolation both read (the seed's "The difference formulas"
and "What the sim does with a lost cycle"), so there is one copy of it.
"""

from __future__ import annotations

import numpy as np

from .tables import DELTA_T


class JointReference:
    """Per robot: the joint reference published as q_d / dq_d / ddq_d.

    ``q``, ``dq``, ``ddq`` are the values of the last cycle (what the robot
    applied and reports back); ``ddq_frozen`` is the acceleration the last two
    commands that actually arrived implied, which a lost cycle continues with.
    """

    def __init__(self, n: int) -> None:
        self.q = np.zeros((n, 7))
        self.dq = np.zeros((n, 7))
        self.ddq = np.zeros((n, 7))
        self.ddq_frozen = np.zeros((n, 7))

    def seed(self, i: int, q: np.ndarray) -> None:
        """Start robot i's motion at rest at ``q`` (a new Move)."""
        self.q[i] = q
        self.dq[i] = 0.0
        self.ddq[i] = 0.0
        self.ddq_frozen[i] = 0.0

    def advance(
        self,
        position_cmd: np.ndarray,
        velocity_cmd: np.ndarray,
        extrapolate: np.ndarray,
        q_c: np.ndarray,
        dq_c: np.ndarray,
        can_extrapolate: np.ndarray,
    ) -> None:
        """Advance every robot's reference by one cycle.

        Args:
            position_cmd: (n,) a q_c arrived for a joint-position motion.
            velocity_cmd: (n,) a dq_c arrived for a joint-velocity motion.
            extrapolate: (n,) a joint motion's cycle went unanswered.
            q_c, dq_c: (n, 7) the cycle's commands (read where the masks say).
            can_extrapolate: (n,) fewer than 20 cycles lost in a row; past
                that the last extrapolated value holds (at rest).
        """
        dt = DELTA_T
        q, dq = self.q, self.dq
        # Backward Euler of the command (libfranka docs/overview.rst).
        dq_from_q = (q_c - q) / dt
        new_dq = np.where(
            position_cmd[:, None], dq_from_q, np.where(velocity_cmd[:, None], dq_c, dq)
        )
        new_ddq = (new_dq - dq) / dt
        arrived = position_cmd | velocity_cmd
        new_q = np.where(
            position_cmd[:, None], q_c, np.where(velocity_cmd[:, None], q + new_dq * dt, q)
        )
        # A lost cycle: semi-implicit Euler at the frozen acceleration (v += a dt,
        # then q += v dt); the same law for dq_c (dq += a dt, no jerk term).
        extra = extrapolate & can_extrapolate
        if extra.any():
            e = extra[:, None]
            ex_dq = dq + self.ddq_frozen * dt
            new_dq = np.where(e, ex_dq, new_dq)
            new_ddq = np.where(e, self.ddq_frozen, new_ddq)
            new_q = np.where(e, q + ex_dq * dt, new_q)
        held = extrapolate & ~can_extrapolate
        if held.any():
            h = held[:, None]
            new_dq = np.where(h, 0.0, new_dq)
            new_ddq = np.where(h, 0.0, new_ddq)
        self.ddq_frozen = np.where(arrived[:, None], new_ddq, self.ddq_frozen)
        self.q, self.dq, self.ddq = new_q, new_dq, new_ddq
