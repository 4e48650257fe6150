"""The torque interface (kExternalController): rows 34 and 32.

docs/fci-behaviour.md "What is checked, and what it latches", torque rows in precedence order:
|tau| <= URDF <limit effort> (tau_J_range_violation, 34), then
|dtau/dt| <= kMaxTorqueRate = 1000 - 1e-3 Nm/s (controller_torque_discontinuity, 32).

The rules' only text is C (fci/limits/_joint.c ``torque_rule`` and ``torque_detail``,
issue 38: one text per rule, compiled): this module hands them the table's limits and
turns their answers into errors and :class:`~.record.Violation`.
"""

from __future__ import annotations

import numpy as np

from ... import native
from ..errors import Error
from ..tables import DELTA_T, RobotTable
from .record import Violation

#: the C text of the rules (a required extension: there is no other)
RULES = native.require("fci.limits._joint", "torque_rule", "torque_detail")

# docs/fci-behaviour.md "Which discontinuity you get depends on the interface": 34 before 32 for a
# torque that breaks both is our ordering, without hardware evidence. Neither row is gated by
# `first` (see check_torque).
_ROWS = {
    Error.tau_j_range_violation: ("range", "Nm"),
    Error.controller_torque_discontinuity: ("rate", "Nm/s"),
}


def check_torque(
    tau_c: np.ndarray,
    tau_prev: np.ndarray,
    first: np.ndarray,
    steps: int | np.ndarray,
    table: RobotTable,
) -> np.ndarray:
    """Judge n commanded torques (tau_J_d); one latched error per robot.

    - **34** where a joint's torque is not within ``|tau| <= table.tau_max`` (the URDF's
      effort limit); a non-finite torque is 34 (docs/fci-behaviour.md: a non-finite
      command is the limits violation of its generator);
    - else **32** where a joint's rate ``(tau_c - tau_prev) / (steps * 1 ms)`` is above
      ``table.dtau_max`` (kMaxTorqueRate - 1e-3).

    Args:
        tau_c: (n, 7) commanded joint torques [Nm].
        tau_prev: (n, 7) the torque the rate is taken against: the last applied
            tau_J_d, or zeros on a torque motion's first command.
        first: (n,) bool, the motion's opening command. Deliberately *not* an
            exemption: docs/limits.md §5 (Franka docs) requires a torque motion to start
            with tau_d = 0, so a non-zero first torque is a step from the zero
            reference and is judged as one (32). Accepted for a uniform signature.
        steps: an int >= 1 for every robot, or (n,) ints: published cycles since
            tau_prev was applied.
        table: the robot's limits.

    Returns:
        (n,) int64: 34, 32 or -1.
    """
    return RULES.torque_rule(tau_c, tau_prev, steps, table.tau_max, table.dtau_max, DELTA_T)


def describe_torque(
    i: int,
    tau_c: np.ndarray,
    tau_prev: np.ndarray,
    first: np.ndarray,
    steps: int | np.ndarray,
    table: RobotTable,
) -> Violation | None:
    """Robot i's violation under :func:`check_torque` (same arguments), or None: in the row
    that won, the first joint whose value is not finite, else the joint furthest beyond
    its bound (the limit given as the bound's magnitude)."""
    found = RULES.torque_detail(
        int(i), tau_c, tau_prev, steps, table.tau_max, table.dtau_max, DELTA_T
    )
    if found is None:
        return None
    error, joint, value, limit = found
    check, unit = _ROWS[error]
    if not np.isfinite(value):
        check = "non-finite"
    return Violation(error, "tau_J_d", joint, value, limit, unit, check)
