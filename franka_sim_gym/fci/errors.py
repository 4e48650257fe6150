"""The robot's 41-entry error enum and libfranka's rendering of it (docs/errors.md §1).

Byte *i* of the state's ``errors`` / ``reflex_reason`` arrays is error *i*. Member
names of :class:`Error` are the ``franka::Errors`` attribute names; ``ERROR_NAMES``
holds the strings libfranka prints (two differ: #31 and #34).
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import IntEnum

import numpy as np

__all__ = ["ERROR_COUNT", "Error", "ERROR_NAMES", "error_names", "format_errors", "error_bits"]

ERROR_COUNT = 41


class Error(IntEnum):
    """Error index on the wire; member names = ``franka::Errors`` attributes (docs/errors.md §1)."""

    joint_position_limits_violation = 0
    cartesian_position_limits_violation = 1
    self_collision_avoidance_violation = 2
    joint_velocity_violation = 3
    cartesian_velocity_violation = 4
    force_control_safety_violation = 5
    joint_reflex = 6
    cartesian_reflex = 7
    max_goal_pose_deviation_violation = 8
    max_path_pose_deviation_violation = 9
    cartesian_velocity_profile_safety_violation = 10
    joint_position_motion_generator_start_pose_invalid = 11
    joint_motion_generator_position_limits_violation = 12
    joint_motion_generator_velocity_limits_violation = 13
    joint_motion_generator_velocity_discontinuity = 14
    joint_motion_generator_acceleration_discontinuity = 15
    cartesian_position_motion_generator_start_pose_invalid = 16
    cartesian_motion_generator_elbow_limit_violation = 17
    cartesian_motion_generator_velocity_limits_violation = 18
    cartesian_motion_generator_velocity_discontinuity = 19
    cartesian_motion_generator_acceleration_discontinuity = 20
    cartesian_motion_generator_elbow_sign_inconsistent = 21
    cartesian_motion_generator_start_elbow_invalid = 22
    force_controller_desired_force_tolerance_violation = 23
    start_elbow_sign_inconsistent = 24
    communication_constraints_violation = 25
    power_limit_violation = 26
    cartesian_motion_generator_joint_position_limits_violation = 27
    cartesian_motion_generator_joint_velocity_limits_violation = 28
    cartesian_motion_generator_joint_velocity_discontinuity = 29
    cartesian_motion_generator_joint_acceleration_discontinuity = 30
    cartesian_position_motion_generator_invalid_frame = 31
    controller_torque_discontinuity = 32
    joint_p2p_insufficient_torque_for_planning = 33
    tau_j_range_violation = 34
    instability_detected = 35
    joint_move_in_wrong_direction = 36
    cartesian_spline_motion_generator_violation = 37
    joint_via_motion_generator_planning_joint_limit_violation = 38
    base_acceleration_initialization_timeout = 39
    base_acceleration_invalid_reading = 40


# Printed strings (libfranka getErrorName): the attribute name except #31 and #34.
_PRINTED_EXCEPTIONS = {
    Error.cartesian_position_motion_generator_invalid_frame: (
        "cartesian_position_motion_generator_invalid_frame_flag"
    ),
    Error.tau_j_range_violation: "tau_J_range_violation",
}

ERROR_NAMES: tuple[str, ...] = tuple(_PRINTED_EXCEPTIONS.get(e, e.name) for e in Error)

assert len(Error) == ERROR_COUNT == len(ERROR_NAMES)
assert [int(e) for e in Error] == list(range(ERROR_COUNT))


def _row(bits: Iterable[bool] | np.ndarray) -> np.ndarray:
    """One bool[41] row; ``ValueError`` for any other shape."""
    row = np.asarray(bits).astype(bool, copy=False)
    if row.shape != (ERROR_COUNT,):
        raise ValueError(f"expected {ERROR_COUNT} error flags, got shape {row.shape}")
    return row


def error_names(bits: Iterable[bool] | np.ndarray) -> tuple[str, ...]:
    """Printed names of the set flags of one bool[41] row, in index order."""
    return tuple(ERROR_NAMES[i] for i in np.flatnonzero(_row(bits)))


def format_errors(bits: Iterable[bool] | np.ndarray) -> str:
    """libfranka's ``Errors`` -> string: ``["a", "b"]``, or ``[]`` when no flag is set."""
    return "[" + ", ".join(f'"{name}"' for name in error_names(bits)) + "]"


def error_bits(*errors: Error | int) -> np.ndarray:
    """A fresh bool[41] row with the given errors set (``ValueError`` for an unknown index)."""
    row = np.zeros(ERROR_COUNT, dtype=bool)
    for error in errors:
        row[int(Error(error))] = True
    return row
