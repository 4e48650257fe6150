"""RobotTable.velocity_envelope_halves: one robot's band is its row of a batch's, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.tables import FR3, JOINT_VELOCITY_LIMIT_TOLERANCE


def test_one_robot_band_is_its_row_of_the_batch_band():
    rng = np.random.default_rng(0)
    q = rng.uniform(FR3.q_lower - 0.1, FR3.q_upper + 0.1, size=(5, 7))
    q[0, 3] = np.nan
    shift = 0.011
    batch = FR3.velocity_envelope_halves(q, shift)
    for i in range(len(q)):
        for one in (q[i], q[i][None], np.asfortranarray(q)[i : i + 1]):
            band = FR3.velocity_envelope_halves(one, shift)
            np.testing.assert_array_equal(band.reshape(14), batch[i])
    # the default tolerance (velocity_envelope) and a per-row shift, the same
    default = FR3.velocity_envelope_halves(q, JOINT_VELOCITY_LIMIT_TOLERANCE)
    upper, lower = FR3.velocity_envelope(q[1:2])
    np.testing.assert_array_equal(upper[0], default[1, :7])
    np.testing.assert_array_equal(lower[0], -default[1, 7:])
    widened = FR3.velocity_envelope_halves(q[1:2], np.full((1, 1), shift))
    np.testing.assert_array_equal(widened[0], batch[1])


def test_the_band_names_positions_of_another_shape():
    with pytest.raises(ValueError, match=r"q: expected joint positions .* got shape \(2, 14\)"):
        FR3.velocity_envelope_halves(np.zeros((2, 14)))
