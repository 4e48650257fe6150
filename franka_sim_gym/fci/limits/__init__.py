"""Pure, vectorised rule functions of the motion-limit engine.

Every ``check_*`` function takes arrays with a leading robot axis n ((n, 7) for
joint signals) and returns an (n,) int64 ``error``: the :class:`~..errors.Error`
index the robot latches this cycle, or ``NO_ERROR`` (-1). One index per robot:
within a generator the rows of docs/fci-behaviour.md "What is checked, and what it
latches" are in precedence order and the first tripped row wins. The per-cycle
path is one call of a C text (fci/limits/_joint.c: the joint, safety and torque rules)
or a fixed handful of numpy operations (the Cartesian rules), with no Python loop over
robots or joints; the matching ``describe_*`` function (same arguments plus the robot
index, called only for a violating robot) recomputes that robot's row and names
the joint, value and limit for the log line (:class:`Violation`).

* :func:`check_joint_position` (q_c): 12 range, 11 start pose, 14, 13, 15;
* :func:`check_joint_velocity` (dq_c): 13 non-finite, 15 start / acceleration / jerk, 13;
* :func:`check_torque` (tau_J_d): 34 range, 32 rate (its only text is C: fci/limits/_joint.c
  ``torque_rule``);
* :func:`check_safety` (measured dq, measured EE speed): 3, 4, one safety-controller error
  per robot, 4 over 3 (its only text is C: fci/limits/_joint.c ``safety_rule``).

What the caller does, not these functions:

* **13 latches 3 with it.** docs/fci-behaviour.md "joint_velocity_violation (3)": when the
  commanded-envelope check (13) trips during a motion, the sim latches the safety
  controller's 3 alongside it in the same abort, without the measured check's
  margin: the margin only guards against a false trip, and here the violation is
  already certain. These functions return one index per generator; pairing 13 with 3 is
  the caller's.
* The safety controller (3, 4, and 2 elsewhere) is not in any generator's chain:
  "they never preempt any row below and no row below preempts them". The caller
  ORs :func:`check_safety`'s error into the latched bits next to the generator's error.
* Choosing the interval ``steps`` (docs/fci-behaviour.md "The difference formulas": the server's
  own count of published cycles since the command the history sits at, never
  widened by the client's echo) and keeping the history. A non-finite command
  is refused whether or not enforcement is on (docs/fci-behaviour.md: NaN "poisons the backward
  differences it would be recorded into"), so it must never be recorded; the
  derivatives these functions return for it are NaN / inf.
* Logging once per error class per motion, and aborting only under
  ``--enforce-motion-limits``.

Constants: every threshold comes from :mod:`..tables` (``ddq_max``, ``dddq_max``
and ``dtau_max`` already "limit - 1e-3", the envelope's tolerance inside
``velocity_envelope``); the start tolerances are arguments (docs/fci-behaviour.md "Two deliberate
departures": 0.1 rad, 0.1 rad/s, sim choices; ``ControllerConfig`` holds them);
the only constant defined here is ``MEASURED_VELOCITY_MARGIN`` (0.1 rad/s, docs/fci-behaviour.md
"joint_velocity_violation (3)").
"""

from .joint import (
    PositionCheck,
    VelocityCheck,
    check_joint_position,
    check_joint_velocity,
    describe_joint_position,
    describe_joint_velocity,
)
from .record import NO_ERROR, Violation
from .safety import (
    MEASURED_VELOCITY_MARGIN,
    PlannedSafety,
    SafetyCheck,
    check_safety,
    describe_safety,
)
from .torque import check_torque, describe_torque

__all__ = [
    "MEASURED_VELOCITY_MARGIN",
    "NO_ERROR",
    "PositionCheck",
    "SafetyCheck",
    "VelocityCheck",
    "Violation",
    "check_joint_position",
    "check_joint_velocity",
    "check_safety",
    "PlannedSafety",
    "check_torque",
    "describe_joint_position",
    "describe_joint_velocity",
    "describe_safety",
    "describe_torque",
]
