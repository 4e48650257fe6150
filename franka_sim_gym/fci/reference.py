"""The commanded joint signal and its backward-Euler history (q_d, dq_d, ddq_d).

One module owns the differencing history that the motion-limit checks and
the lost-cycle extrapolation both read (the seed's "The difference formulas"
and "What the sim does with a lost cycle"), so there is one copy of it.

The arrays are the published q_d / dq_d / ddq_d themselves (views into the
state's float64 shadow), updated in place: what the robot applied is exactly
what it reports, and the next command is differenced against that.
"""

from __future__ import annotations

import numpy as np

from .tables import DELTA_T

_RATE = 1.0 / DELTA_T


class JointReference:
    """Per robot: the joint reference published as q_d / dq_d / ddq_d.

    ``ddq_frozen`` is the acceleration the last two commands that actually
    arrived implied, which a lost cycle continues with (frozen, not re-derived
    from extrapolated samples: seed "Frozen, not continued").
    """

    def __init__(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> None:
        self.q, self.dq, self.ddq = q, dq, ddq
        self.ddq_frozen = np.zeros_like(q)
        self._dq_new = np.empty_like(q)

    def seed(self, i: int, q: np.ndarray) -> None:
        """Start robot i's motion at rest at ``q`` (a new Move)."""
        self.q[i] = q
        self.dq[i] = 0.0
        self.ddq[i] = 0.0
        self.ddq_frozen[i] = 0.0

    def apply_positions(self, q_c: np.ndarray) -> None:
        """Every robot received a q_c this cycle (the common case, no masks)."""
        dq_new = self._dq_new
        np.subtract(q_c, self.q, out=dq_new)
        dq_new *= _RATE
        np.subtract(dq_new, self.dq, out=self.ddq)
        self.ddq *= _RATE
        self.dq[...] = dq_new
        self.q[...] = q_c
        self.ddq_frozen[...] = self.ddq

    def advance(
        self,
        position_cmd: np.ndarray,
        velocity_cmd: np.ndarray,
        extrapolate: np.ndarray,
        q_c: np.ndarray,
        dq_c: np.ndarray,
        can_extrapolate: np.ndarray,
    ) -> None:
        """Advance the robots of the masks by one cycle (the general, masked path).

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
        pc, vc = position_cmd[:, None], velocity_cmd[:, None]
        # Backward Euler of the command (libfranka docs/overview.rst).
        new_dq = np.where(pc, (q_c - q) * _RATE, np.where(vc, dq_c, dq))
        new_ddq = (new_dq - dq) * _RATE
        new_q = np.where(pc, q_c, np.where(vc, q + new_dq * dt, q))
        # A lost cycle: semi-implicit Euler at the frozen acceleration (v += a dt,
        # then q += v dt); the same law for dq_c (dq += a dt, no jerk term).
        extra = (extrapolate & can_extrapolate)[:, None]
        ex_dq = dq + self.ddq_frozen * dt
        new_dq = np.where(extra, ex_dq, new_dq)
        new_ddq = np.where(extra, self.ddq_frozen, new_ddq)
        new_q = np.where(extra, q + ex_dq * dt, new_q)
        # Past 20 lost cycles the last extrapolated value holds, at rest.
        held = (extrapolate & ~can_extrapolate)[:, None]
        new_dq = np.where(held, 0.0, new_dq)
        new_ddq = np.where(held, 0.0, new_ddq)
        touched = (position_cmd | velocity_cmd | extrapolate)[:, None]
        np.copyto(self.ddq_frozen, new_ddq, where=(position_cmd | velocity_cmd)[:, None])
        np.copyto(self.q, new_q, where=touched)
        np.copyto(self.dq, new_dq, where=touched)
        np.copyto(self.ddq, new_ddq, where=touched)
