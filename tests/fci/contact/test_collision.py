"""SetCollisionBehavior's thresholds (fci/contact/collision.py): the defaults and what a payload
may carry. The comparisons and the phases are the sensing step's C text
(tests/fci/contact/test_contact_rules.py)."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.contact.collision import (
    DEFAULT_FORCE_THRESHOLDS,
    DEFAULT_TORQUE_THRESHOLDS,
    THRESHOLD_NAMES,
    CollisionBehavior,
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


@pytest.mark.parametrize("bad", [np.nan, np.inf, -1.0])
def test_a_non_finite_or_negative_threshold_is_refused_naming_its_array(bad):
    values = payload(10.0, 30.0, 10.0, 30.0)
    values["upper_force_thresholds_nominal"][3] = bad
    assert invalid_thresholds(values).startswith("upper_force_thresholds_nominal: ")


def test_a_lower_threshold_above_its_upper_one_is_accepted():
    assert invalid_thresholds(payload(40.0, 20.0, 40.0, 20.0)) is None
