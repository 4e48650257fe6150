"""The error enum and its rendering match docs/errors.md §1."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.errors import (
    ERROR_COUNT,
    ERROR_NAMES,
    Error,
    error_bits,
    error_names,
    format_errors,
)

# docs/errors.md §1, column "Errors attribute", transcribed in index order.
ATTRIBUTES = [
    "joint_position_limits_violation",
    "cartesian_position_limits_violation",
    "self_collision_avoidance_violation",
    "joint_velocity_violation",
    "cartesian_velocity_violation",
    "force_control_safety_violation",
    "joint_reflex",
    "cartesian_reflex",
    "max_goal_pose_deviation_violation",
    "max_path_pose_deviation_violation",
    "cartesian_velocity_profile_safety_violation",
    "joint_position_motion_generator_start_pose_invalid",
    "joint_motion_generator_position_limits_violation",
    "joint_motion_generator_velocity_limits_violation",
    "joint_motion_generator_velocity_discontinuity",
    "joint_motion_generator_acceleration_discontinuity",
    "cartesian_position_motion_generator_start_pose_invalid",
    "cartesian_motion_generator_elbow_limit_violation",
    "cartesian_motion_generator_velocity_limits_violation",
    "cartesian_motion_generator_velocity_discontinuity",
    "cartesian_motion_generator_acceleration_discontinuity",
    "cartesian_motion_generator_elbow_sign_inconsistent",
    "cartesian_motion_generator_start_elbow_invalid",
    "force_controller_desired_force_tolerance_violation",
    "start_elbow_sign_inconsistent",
    "communication_constraints_violation",
    "power_limit_violation",
    "cartesian_motion_generator_joint_position_limits_violation",
    "cartesian_motion_generator_joint_velocity_limits_violation",
    "cartesian_motion_generator_joint_velocity_discontinuity",
    "cartesian_motion_generator_joint_acceleration_discontinuity",
    "cartesian_position_motion_generator_invalid_frame",
    "controller_torque_discontinuity",
    "joint_p2p_insufficient_torque_for_planning",
    "tau_j_range_violation",
    "instability_detected",
    "joint_move_in_wrong_direction",
    "cartesian_spline_motion_generator_violation",
    "joint_via_motion_generator_planning_joint_limit_violation",
    "base_acceleration_initialization_timeout",
    "base_acceleration_invalid_reading",
]


def test_there_are_41_errors_with_the_attribute_names_in_index_order():
    assert ERROR_COUNT == 41
    assert len(ATTRIBUTES) == 41
    assert [e.name for e in Error] == ATTRIBUTES
    assert [e.value for e in Error] == list(range(41))
    assert len(ERROR_NAMES) == 41


def test_printed_names_equal_attributes_except_31_and_34():
    assert ERROR_NAMES[31] == "cartesian_position_motion_generator_invalid_frame_flag"
    assert ERROR_NAMES[34] == "tau_J_range_violation"
    for i, attribute in enumerate(ATTRIBUTES):
        if i not in (31, 34):
            assert ERROR_NAMES[i] == attribute, i


def test_format_errors_with_no_flag_is_empty_brackets():
    assert format_errors(np.zeros(41, dtype=bool)) == "[]"
    assert error_names(np.zeros(41, dtype=bool)) == ()


def test_format_errors_with_one_flag_quotes_the_printed_name():
    assert format_errors(error_bits(Error.tau_j_range_violation)) == '["tau_J_range_violation"]'


def test_format_errors_with_two_flags_is_index_order_comma_space():
    # Given out of order: output follows the index, like libfranka's loop.
    bits = error_bits(Error.cartesian_reflex, Error.joint_velocity_violation)
    assert format_errors(bits) == '["joint_velocity_violation", "cartesian_reflex"]'
    assert error_names(bits) == ("joint_velocity_violation", "cartesian_reflex")


def test_error_names_reads_a_wire_row_of_bytes():
    row = np.zeros(41, dtype=np.uint8)
    row[31] = 1
    assert error_names(row) == ("cartesian_position_motion_generator_invalid_frame_flag",)


def test_error_bits_sets_exactly_the_given_indices():
    bits = error_bits(0, Error.base_acceleration_invalid_reading)
    assert bits.shape == (41,) and bits.dtype == np.bool_
    assert np.flatnonzero(bits).tolist() == [0, 40]
    assert not error_bits().any()


def test_error_bits_rejects_an_unknown_index():
    with pytest.raises(ValueError):
        error_bits(41)


def test_a_row_of_the_wrong_length_is_rejected():
    with pytest.raises(ValueError):
        format_errors(np.zeros(40, dtype=bool))
