"""SetCollisionBehavior's thresholds and phases (fci/collision.py), rule by rule."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.collision import (
    ACCELERATION_PHASE,
    DEFAULT_FORCE_THRESHOLDS,
    DEFAULT_TORQUE_THRESHOLDS,
    THRESHOLD_NAMES,
    CollisionBehavior,
    accelerating,
    invalid_thresholds,
)


def payload(torque_lower, torque_upper, force_lower, force_upper, nominal_scale=1.0):
    """An 8-array payload; the nominal phase's thresholds are the acceleration phase's
    times ``nominal_scale`` (1: libfranka's 4-argument overload)."""
    t_lo, t_up = np.full(7, torque_lower, float), np.full(7, torque_upper, float)
    f_lo, f_up = np.full(6, force_lower, float), np.full(6, force_upper, float)
    s = nominal_scale
    arrays = (t_lo, t_up, t_lo * s, t_up * s, f_lo, f_up, f_lo * s, f_up * s)
    return dict(zip(THRESHOLD_NAMES, arrays, strict=True))


def test_before_any_call_the_thresholds_are_libfrankas_default_behaviour():
    b = CollisionBehavior(2)
    np.testing.assert_array_equal(b.lower_torque[1, 1], DEFAULT_TORQUE_THRESHOLDS)
    np.testing.assert_array_equal(b.upper_force[0, 0], DEFAULT_FORCE_THRESHOLDS)


def test_between_lower_and_upper_a_contact_above_upper_a_collision():
    b = CollisionBehavior(1)
    b.configure(0, payload(10.0, 30.0, 5.0, 20.0))
    quiet = [False]
    tau = np.array([[0.0, 12.0, -31.0, 0.0, 9.9, 0.0, 0.0]])
    wrench = np.array([[0.0, 0.0, -25.0, 6.0, 0.0, 0.0]])
    levels = b.levels(tau, wrench, np.array(quiet))
    np.testing.assert_array_equal(levels.joint_contact[0], [0, 1, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(levels.joint_over[0], [0, 0, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(levels.cartesian_contact[0], [0, 0, 1, 1, 0, 0])
    np.testing.assert_array_equal(levels.cartesian_over[0], [0, 0, 1, 0, 0, 0])


def test_the_acceleration_phase_uses_its_own_thresholds():
    b = CollisionBehavior(2)
    b.configure(0, payload(10.0, 30.0, 10.0, 30.0, nominal_scale=0.5))
    b.configure(1, payload(10.0, 30.0, 10.0, 30.0, nominal_scale=0.5))
    tau = np.full((2, 7), 20.0)
    ddq_d = np.array([[0.0] * 7, [0.0, 0.0, 2 * ACCELERATION_PHASE, 0.0, 0.0, 0.0, 0.0]])
    phase = accelerating(ddq_d, np.array([True, True]))
    np.testing.assert_array_equal(phase, [False, True])
    levels = b.levels(tau, np.zeros((2, 6)), phase)
    # Nominal: upper 15 Nm, crossed; acceleration: upper 30 Nm, not.
    assert levels.joint_over[0].all() and not levels.joint_over[1].any()
    # Outside a motion, nominal.
    assert not accelerating(ddq_d, np.array([False, False])).any()


@pytest.mark.parametrize("bad", [np.nan, np.inf, -1.0])
def test_a_non_finite_or_negative_threshold_is_refused_naming_its_array(bad):
    values = payload(10.0, 30.0, 10.0, 30.0)
    values["upper_force_thresholds_nominal"][3] = bad
    assert invalid_thresholds(values).startswith("upper_force_thresholds_nominal: ")


def test_a_lower_threshold_above_its_upper_one_is_accepted():
    assert invalid_thresholds(payload(40.0, 20.0, 40.0, 20.0)) is None
