"""The measured joint fields' one text (fci/_measured.c): q, theta, dq, dtheta, tau_J and
dtau_J from the physics and the sensors' noise (docs/robot-state.md, docs/reality.md)."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym import native

MEASURED = native.require("fci._measured", "measured")
RATE = 1.0 / 1e-3


def fields(n):
    return [np.full((n, 7), 7.0) for _ in range(6)]  # q, theta, dq, dtheta, tau_J, dtau_J


def test_the_ideal_robot_reports_the_physics_and_the_torque_s_backward_difference():
    rng = np.random.default_rng(0)
    q, dq, tau = rng.normal(size=(3, 2, 7))
    q[0, 0] = -0.0  # a copy, not a sum: the sign of a zero is kept
    out = fields(2)
    prev = out[4].copy()
    MEASURED.measured(q, dq, tau, None, *out, RATE)
    q_out, theta, dq_out, dtheta, tau_out, dtau = out
    assert q_out.tobytes() == q.tobytes() and theta.tobytes() == q.tobytes()
    assert dq_out.tobytes() == dq.tobytes() and dtheta.tobytes() == dq.tobytes()
    assert tau_out.tobytes() == tau.tobytes()
    np.testing.assert_array_equal(dtau, (tau - prev) * RATE)


def test_the_sensors_noise_is_added_to_each_field_and_to_what_derives_from_it():
    rng = np.random.default_rng(1)
    q, dq, tau = rng.normal(size=(3, 3, 7))
    noise = rng.normal(size=(3, 21))
    out = fields(3)
    MEASURED.measured(q, dq, tau, noise, *out, RATE)
    q_out, theta, dq_out, dtheta, tau_out, dtau = out
    np.testing.assert_array_equal(q_out, q + noise[:, :7])
    np.testing.assert_array_equal(theta, q_out)
    np.testing.assert_array_equal(dq_out, dq + noise[:, 7:14])
    np.testing.assert_array_equal(dtheta, dq_out)
    np.testing.assert_array_equal(tau_out, tau + noise[:, 14:])
    np.testing.assert_array_equal(dtau, (tau + noise[:, 14:] - 7.0) * RATE)


def test_a_wrong_shape_is_a_value_error_naming_the_array():
    q = np.zeros((2, 7))
    with pytest.raises(ValueError, match="noise: axis 1 has length 14, expected 21"):
        MEASURED.measured(q, q, q, np.zeros((2, 14)), *fields(2), RATE)
    with pytest.raises(ValueError, match="dtau_out: axis 0 has length 3, expected 2"):
        MEASURED.measured(q, q, q, None, *fields(2)[:5], np.zeros((3, 7)), RATE)
