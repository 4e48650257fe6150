"""The torque interface (kExternalController): rows 34 and 32.

docs/fci-behaviour.md "What is checked, and what it latches", torque rows in precedence order:
|tau| <= URDF <limit effort> (tau_J_range_violation, 34), then
|dtau/dt| <= kMaxTorqueRate = 1000 - 1e-3 Nm/s (controller_torque_discontinuity, 32).
"""

from __future__ import annotations

import numpy as np

from ..errors import Error
from ..tables import RobotTable
from .precedence import (
    NO_ERROR,
    Precedence,
    Row,
    Violation,
    as_bool,
    describe_row,
    interval,
    robot_row,
    stack,
)

# docs/fci-behaviour.md "Which discontinuity you get depends on the interface": 34 before 32 for a
# torque that breaks both is our ordering, without hardware evidence. Neither row is gated by
# `first` (see check_torque).
_TORQUE = Precedence(
    codes=(
        Error.tau_j_range_violation,  # 34 range (and non-finite)
        Error.controller_torque_discontinuity,  # 32 rate
    )
)


def _torque_terms(tau_c, tau_prev, steps, table):
    rate = (tau_c - tau_prev) / interval(steps)
    # "not inside" so that NaN lands on 34 (docs/fci-behaviour.md: a non-finite command is the
    # limits violation of its generator; on the torque interface that is 34).
    masks = [~(np.abs(tau_c) <= table.tau_max), np.abs(rate) > table.dtau_max]
    return masks, rate


def check_torque(
    tau_c: np.ndarray,
    tau_prev: np.ndarray,
    first: np.ndarray,
    steps: np.ndarray,
    table: RobotTable,
) -> np.ndarray:
    """Judge n commanded torques (tau_J_d); one latched error per robot.

    Args:
        tau_c: (n, 7) commanded joint torques [Nm].
        tau_prev: (n, 7) the torque the rate is taken against: the last applied
            tau_J_d, or zeros on a torque motion's first command.
        first: (n,) bool, the motion's opening command. Deliberately *not* an
            exemption: docs/limits.md §5 (Franka docs) requires a torque motion to start
            with tau_d = 0, so a non-zero first torque is a step from the zero
            reference and is judged as one (32). Accepted for a uniform signature.
        steps: (n,) int >= 1, published cycles since tau_prev was applied.
        table: the robot's limits.

    Returns:
        (n,) int64: 34 (|tau| > tau_max, or non-finite), 32 (rate) or -1.
    """
    (r34, r32), _ = _torque_terms(tau_c, tau_prev, steps, table)
    if not (r34 | r32).any():  # all-or-none
        return np.full(r34.shape[0], NO_ERROR, np.int64)
    return _TORQUE.select(stack(r34, r32), as_bool(first))


def describe_torque(
    i: int,
    tau_c: np.ndarray,
    tau_prev: np.ndarray,
    first: np.ndarray,
    steps: np.ndarray,
    table: RobotTable,
) -> Violation | None:
    """Robot i's violation under :func:`check_torque` (same arguments), or None."""
    tau_c, tau_prev, steps = (robot_row(a, i) for a in (tau_c, tau_prev, steps))
    masks, rate = _torque_terms(tau_c, tau_prev, steps, table)
    tripped = stack(*masks)
    k = _TORQUE.first_row(tripped[0], False)
    if k is None:
        return None
    row = (
        Row(34, "range", "tau_J_d", "Nm", tau_c, table.tau_max, -table.tau_max, True),
        Row(32, "rate", "tau_J_d", "Nm/s", rate, table.dtau_max, -table.dtau_max, True),
    )[k]
    return describe_row(row, tripped[0, k])
