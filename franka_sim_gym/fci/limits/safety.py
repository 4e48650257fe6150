"""The safety controller's velocity halves, on measured state: errors 3 and 4.

docs/fci-behaviour.md "joint_velocity_violation (3)" and "cartesian_velocity_violation (4)". Not
part of any generator's precedence chain (docs/fci-behaviour.md "What is checked, and what it
latches"); judged once per cycle in every control mode. Self-collision (2) needs contacts and is
not here.

The rules' only text is C (fci/limits/_joint.c ``safety_rule`` and ``safety_detail``, issue 38:
one text per rule, compiled): this module hands them the table's constants and turns their
answers into :class:`SafetyCheck` and :class:`~.record.Violation`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ... import native
from ..errors import Error
from ..tables import DELTA_T, JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from .record import Violation

#: docs/fci-behaviour.md "joint_velocity_violation (3)": "The sim allows a 0.1 rad/s margin above
#: the envelope before firing" (measured dq carries integrator ring / contact spikes).
#: Same value as ControllerConfig.measured_velocity_margin, which the caller passes.
MEASURED_VELOCITY_MARGIN = 0.1

#: the C text of the rules (a required extension: there is no other)
RULES = native.require("fci.limits._joint", "safety_rule", "safety_detail", "SafetyPlan")


class SafetyCheck(NamedTuple):
    """:func:`check_safety`'s answer."""

    #: (n,) int64: 4 (cartesian_velocity_violation), 3 (joint_velocity_violation) or -1
    error: np.ndarray
    #: (n,) bool: an error, on a robot in motion
    bad: np.ndarray
    #: how many robots are bad
    count: int


def check_safety(
    dq: np.ndarray,
    q: np.ndarray,
    ee: np.ndarray,
    ee_prev: np.ndarray,
    in_motion: np.ndarray,
    table: RobotTable,
    margin: float = MEASURED_VELOCITY_MARGIN,
) -> SafetyCheck:
    """Errors 3 and 4 of every robot this cycle, 4 outranking 3.

    - **3** where a joint's measured ``dq`` is outside the velocity envelope at its
      measured ``q`` (``table.velocity_envelope``) widened by ``margin`` on either side;
    - **4** where the end effector's measured translational speed, the backward
      difference of its measured position (``ee_prev`` a cycle before ``ee``) over the
      1 ms cycle, exceeds ``table.v_trans_max`` (kMaxTranslationalVelocity = 3 - 1e-3
      m/s: translation only, no rotational bound: hardware answers 3, not 4, for a
      fast-spinning EE; no margin);
    - **4 outranks 3** (docs/fci-behaviour.md "cartesian_velocity_violation (4)": with the EE
      moved 0.5 m out, a joint velocity ramp is reported as cartesian_velocity_violation
      by itself: a cycle that breaks both latches 4 only).

    A non-finite reading is a violation (a physics state gone NaN is not "the arm is
    within its limits"). A robot whose backend publishes no reading must be left out by
    the caller (docs/fci-behaviour.md: such a backend "is left alone rather than read as
    'the arm is clear'").

    Args:
        dq, q: (n, 7) measured joint velocity [rad/s] and position [rad].
        ee, ee_prev: (n, 3) the measured EE position [m] this cycle and the one before.
        in_motion: (n,) bool: the robots whose errors count (``bad``).
        table: the robot's limits.
        margin: [rad/s] allowed beyond the envelope on either side.
    """
    constants, positional = table.joint_constants
    error, bad, count = RULES.safety_rule(
        dq, q, ee, ee_prev, constants, positional,
        JOINT_VELOCITY_LIMIT_TOLERANCE, margin, table.v_trans_max, DELTA_T, in_motion,
    )  # fmt: skip
    return SafetyCheck(error, bad, count)


class PlannedSafety:
    """:func:`check_safety` on arrays held for every cycle (the safety controller's):
    :meth:`run` judges them as they are then and writes :attr:`error` and :attr:`bad`.

    Args:
        dq, q: (n, 7) measured joint velocity and position (read at each run).
        ee, ee_prev: (n, 3) the measured EE position this cycle and the one before.
        table: the robot's limits.
        margin: [rad/s] allowed beyond the envelope on either side.
    """

    def __init__(
        self,
        dq: np.ndarray,
        q: np.ndarray,
        ee: np.ndarray,
        ee_prev: np.ndarray,
        table: RobotTable,
        margin: float = MEASURED_VELOCITY_MARGIN,
    ) -> None:
        n = len(dq)
        #: (n,) int64: 4, 3 or -1, as :class:`SafetyCheck`'s error
        self.error = np.full(n, -1, dtype=np.int64)
        self._bad = np.zeros(n, dtype=np.uint8)
        #: (n,) bool: an error, on a robot in motion (a view of the C text's flags)
        self.bad = self._bad.view(bool)
        constants, positional = table.joint_constants
        self._plan = RULES.SafetyPlan(
            dq, q, ee, ee_prev, constants, positional,
            JOINT_VELOCITY_LIMIT_TOLERANCE, margin, table.v_trans_max, DELTA_T,
            self.error, self._bad,
        )  # fmt: skip

    def run(self, in_motion: np.ndarray) -> int:
        """Errors 3 and 4 of every robot now (``in_motion`` (n,) bool: whose count);
        returns how many robots are bad."""
        return self._plan.run(in_motion)


def describe_safety(
    i: int,
    dq: np.ndarray,
    q: np.ndarray,
    ee: np.ndarray,
    ee_prev: np.ndarray,
    table: RobotTable,
    margin: float = MEASURED_VELOCITY_MARGIN,
) -> Violation | None:
    """Robot i's error under :func:`check_safety`, for the log line, or None.

    For 4 the EE's speed and its limit; for 3 the first joint whose dq is not finite,
    else the joint furthest outside its widened envelope, with the bound it crossed (the
    envelope bound widened by ``margin``).
    """
    constants, positional = table.joint_constants
    found = RULES.safety_detail(
        int(i), dq, q, ee, ee_prev, constants, positional,
        JOINT_VELOCITY_LIMIT_TOLERANCE, margin, table.v_trans_max, DELTA_T,
    )  # fmt: skip
    if found is None:
        return None
    error, joint, value, upper, lower = found
    if error == Error.cartesian_velocity_violation:
        return Violation(error, "|v_EE|", -1, value, upper, "m/s", "translational speed")
    if not np.isfinite(value):
        return Violation(error, "dq", joint, value, float("nan"), "rad/s", "non-finite")
    limit = upper if value - upper >= lower - value else lower
    return Violation(error, "dq", joint, value, limit, "rad/s", "envelope + margin")
