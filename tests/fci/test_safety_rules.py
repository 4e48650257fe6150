"""The safety controller's rules (fci/limits/safety.py): the measured joint velocity (3)
and Cartesian speed (4), 4 outranking 3 (docs/fci-behaviour.md "joint_velocity_violation
(3)" and "cartesian_velocity_violation (4)")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.limits import (
    MEASURED_VELOCITY_MARGIN,
    NO_ERROR,
    check_measured_cartesian_speed,
    check_measured_joint_velocity,
    describe_measured_cartesian_speed,
    describe_measured_joint_velocity,
    safety_error,
)
from franka_sim_gym.fci.tables import FR3
from tests.limit_rules_helpers import E3, E4, HOME, as_batch, on

# NaN / inf inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")


# --- safety controller: 3 / 4 ----------------------------------------------------


def _measured_joint(dq, q=HOME, margin=MEASURED_VELOCITY_MARGIN):
    error = int(check_measured_joint_velocity(as_batch(dq), as_batch(q), FR3, margin)[0])
    return error, describe_measured_joint_velocity(0, as_batch(dq), as_batch(q), FR3, margin)


def _measured_speed(v):
    error = int(check_measured_cartesian_speed(as_batch(v), FR3)[0])
    return error, describe_measured_cartesian_speed(0, as_batch(v), FR3)


def test_measured_joint_velocity_beyond_envelope_plus_margin_is_3():
    error, why = _measured_joint(on(0, 2.619 + 0.1 + 0.01))
    assert (error, why.joint, why.signal) == (E3, 0, "dq")
    assert why.limit == pytest.approx(2.719)
    assert _measured_joint(on(1, -2.0800 - 0.11))[0] == E3
    # Inside the margin, and 0.99 x the envelope: nothing.
    assert _measured_joint(on(0, 2.619 + 0.09))[0] == NO_ERROR
    assert _measured_joint(on(1, 0.99 * -2.0800))[0] == NO_ERROR
    # The margin is an argument: with none, the envelope itself.
    assert _measured_joint(on(0, 2.62), margin=0.0)[0] == E3


def test_measured_cartesian_speed_above_3_m_per_s_is_4():
    for v in ((3.0, 0.0, 0.0), (2.0, 2.0, 1.0), (0.0, 0.0, -2.999 - 1e-6)):
        error, why = _measured_speed(v)
        assert (error, why.joint) == (E4, -1)
        assert why.limit == pytest.approx(2.999)
    assert _measured_speed((0.99 * 2.999, 0.0, 0.0))[0] == NO_ERROR
    assert _measured_speed((1.7, 1.7, 1.0))[0] == NO_ERROR  # 2.6 m/s


def test_measured_cartesian_speed_outranks_joint_velocity():
    joint = np.array([E3, E3, NO_ERROR, NO_ERROR])
    cartesian = np.array([E4, NO_ERROR, E4, NO_ERROR])
    assert safety_error(joint, cartesian).tolist() == [E4, E3, E4, NO_ERROR]


def test_non_finite_measured_velocity_is_a_violation():
    assert _measured_joint(on(0, math.nan))[0] == E3
    assert _measured_speed((math.nan, 0.0, 0.0))[0] == E4
