"""Shared by the limit-rule tests (tests/fci/test_*_rules*.py): the FR3 at home, the
error indices, and one robot's call of the joint rules."""

from __future__ import annotations

import math

import numpy as np

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.limits import (
    check_joint_position,
    check_joint_velocity,
    describe_joint_position,
    describe_joint_velocity,
)
from franka_sim_gym.fci.tables import FR3

DT = 1e-3
TOL = 0.1  # docs/fci-behaviour.md "Two deliberate departures": 0.1 rad and 0.1 rad/s (sim choices)
HOME = np.array([0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])
Z = np.zeros(7)

E12 = Error.joint_motion_generator_position_limits_violation
E11 = Error.joint_position_motion_generator_start_pose_invalid
E13 = Error.joint_motion_generator_velocity_limits_violation
E14 = Error.joint_motion_generator_velocity_discontinuity
E15 = Error.joint_motion_generator_acceleration_discontinuity
E32 = Error.controller_torque_discontinuity
E34 = Error.tau_j_range_violation
E3 = Error.joint_velocity_violation
E4 = Error.cartesian_velocity_violation


def on(j: int, x: float, base=Z) -> np.ndarray:
    """``base`` with joint j (0-based) offset by x."""
    v = np.array(base, dtype=float)
    v[j] += x
    return v


def as_batch(x) -> np.ndarray:
    """One robot's values as a batch of one (a leading robot axis)."""
    return np.asarray(x, dtype=float).reshape(1, -1)


def position(
    q_c, q_prev=HOME, dq_prev=Z, ddq_prev=Z, first=False, q_start=None, steps=1, table=FR3
):
    """One robot's check_joint_position; returns (error, describe, result)."""
    args = (
        as_batch(q_c),
        as_batch(q_prev),
        as_batch(dq_prev),
        as_batch(ddq_prev),
        np.array([first]),
        as_batch(q_prev if q_start is None else q_start),
        np.array([steps]),
        table,
        TOL,
    )
    result = check_joint_position(*args)
    return int(result.error[0]), describe_joint_position(0, *args), result


def velocity(
    dq_c, q_prev=HOME, dq_prev=Z, ddq_prev=Z, first=False, dq_start=None, steps=1, table=FR3
):
    """One robot's check_joint_velocity; returns (error, describe, result)."""
    args = (
        as_batch(dq_c),
        as_batch(q_prev),
        as_batch(dq_prev),
        as_batch(ddq_prev),
        np.array([first]),
        as_batch(dq_prev if dq_start is None else dq_start),
        np.array([steps]),
        table,
        TOL,
    )
    result = check_joint_velocity(*args)
    return int(result.error[0]), describe_joint_velocity(0, *args), result


def moving(v: np.ndarray, steps: int = 1):
    """q_c from HOME for a stream whose new implied velocity is ``v`` (over ``steps``)."""
    return HOME + np.asarray(v) * steps * DT
