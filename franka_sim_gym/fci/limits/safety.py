"""The safety controller's velocity halves, on measured state: errors 3 and 4.

docs/fci-behaviour.md "joint_velocity_violation (3)" and "cartesian_velocity_violation (4)". Not
part of any generator's precedence chain (docs/fci-behaviour.md "What is checked, and what it
latches"); judged once per cycle in every control mode. Self-collision (2) needs contacts and is
not here.
"""

from __future__ import annotations

import numpy as np

from ..errors import Error
from ..tables import JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from .joint import KERNEL, joint_constants
from .precedence import NO_ERROR, Row, Violation, describe_row, robot_row

#: docs/fci-behaviour.md "joint_velocity_violation (3)": "The sim allows a 0.1 rad/s margin above
#: the envelope before firing" (measured dq carries integrator ring / contact spikes).
#: Same value as ControllerConfig.measured_velocity_margin, which the caller passes.
MEASURED_VELOCITY_MARGIN = 0.1

_JOINT = int(Error.joint_velocity_violation)
_CARTESIAN = int(Error.cartesian_velocity_violation)


def check_measured_joint_velocity(
    dq: np.ndarray,
    q: np.ndarray,
    table: RobotTable,
    margin: float = MEASURED_VELOCITY_MARGIN,
) -> np.ndarray:
    """3 where measured dq leaves the envelope at measured q by more than ``margin``.

    Args:
        dq, q: (n, 7) measured joint velocity [rad/s] and position [rad].
        table: the robot's limits (``velocity_envelope``).
        margin: [rad/s] allowed beyond the envelope on either side.

    Returns:
        (n,) int64: 3 or -1. A non-finite measured dq is a violation (3): a physics
        state gone NaN is not "the arm is within its limits".
    """
    if KERNEL is not None:  # the same comparisons in C (fci/limits/_joint.c)
        outside = np.empty(len(dq), np.uint8)
        constants, positional = joint_constants(table)
        shift = JOINT_VELOCITY_LIMIT_TOLERANCE
        KERNEL.measured_velocity_rows(dq, q, constants, positional, shift, margin, outside)
        return np.where(outside, _JOINT, NO_ERROR)
    upper, lower = table.velocity_envelope(q)
    inside = (dq <= upper + margin) & (dq >= lower - margin)
    return np.where(inside.all(axis=1), NO_ERROR, _JOINT)


def check_measured_cartesian_speed(v_ee: np.ndarray, table: RobotTable) -> np.ndarray:
    """4 where the measured end-effector translational speed exceeds ``table.v_trans_max``.

    docs/fci-behaviour.md "cartesian_velocity_violation (4)": translation only (no rotational
    bound: hardware answers 3, not 4, for a fast-spinning EE), limit
    kMaxTranslationalVelocity = 3 - 1e-3 m/s, no margin.

    Args:
        v_ee: (n, 3) measured EE translational velocity [m/s]. Robots whose
            backend publishes no reading must be left out by the caller (docs/fci-behaviour.md: such
            a backend "is left alone rather than read as 'the arm is clear'").
        table: the robot's limits.

    Returns:
        (n,) int64: 4 or -1 (4 for a non-finite reading, as for 3).
    """
    speed = np.sqrt((v_ee * v_ee).sum(axis=1))
    return np.where(speed <= table.v_trans_max, NO_ERROR, _CARTESIAN)


def safety_error(joint: np.ndarray, cartesian: np.ndarray) -> np.ndarray:
    """One safety-controller error per robot: 4 outranks 3.

    docs/fci-behaviour.md "cartesian_velocity_violation (4)": with the EE moved 0.5 m out, a joint
    velocity ramp is reported as cartesian_velocity_violation by itself: a cycle
    that breaks both latches 4 only.
    """
    return np.where(cartesian != NO_ERROR, cartesian, joint)


def describe_measured_joint_velocity(
    i: int,
    dq: np.ndarray,
    q: np.ndarray,
    table: RobotTable,
    margin: float = MEASURED_VELOCITY_MARGIN,
) -> Violation | None:
    """Robot i's violation under :func:`check_measured_joint_velocity`, or None.

    ``limit`` is the threshold applied: the envelope bound widened by ``margin``.
    """
    dq, q = robot_row(dq, i), robot_row(q, i)
    upper, lower = table.velocity_envelope(q)
    tripped = ~((dq <= upper + margin) & (dq >= lower - margin))
    if not tripped.any():
        return None
    row = Row(_JOINT, "envelope + margin", "dq", "rad/s", dq, upper + margin, lower - margin)
    return describe_row(row, tripped)


def describe_measured_cartesian_speed(
    i: int, v_ee: np.ndarray, table: RobotTable
) -> Violation | None:
    """Robot i's violation under :func:`check_measured_cartesian_speed`, or None."""
    v = np.asarray(v_ee, dtype=np.float64)[i]
    speed = float(np.sqrt((v * v).sum()))
    if speed <= table.v_trans_max:
        return None
    limit = table.v_trans_max
    return Violation(_CARTESIAN, "|v_EE|", -1, speed, limit, "m/s", "translational speed")
