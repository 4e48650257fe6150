"""RobotTable.velocity_envelope_halves: one robot's band is its row of a batch's, bit for bit."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.fci.tables import FR3, JOINT_VELOCITY_LIMIT_TOLERANCE


def test_one_robot_band_is_its_row_of_the_batch_band():
    rng = np.random.default_rng(0)
    q = rng.uniform(FR3.q_lower - 0.1, FR3.q_upper + 0.1, size=(5, 7))
    q[0, 3] = np.nan
    shift = 0.011
    batch = FR3.velocity_envelope_halves(q, shift)
    for i in range(len(q)):
        row = q[i]
        doubled = np.concatenate((row, row))[None]
        # (q | q) as a strided view: written in place and returned, as a contiguous one
        storage = np.zeros((1, 28))
        strided = storage[:, ::2]
        strided[...] = doubled
        for one in (row, row[None], doubled.copy(), strided):
            band = FR3.velocity_envelope_halves(one, shift)
            np.testing.assert_array_equal(band.reshape(14), batch[i])
        assert np.array_equal(strided, batch[i][None], equal_nan=True)
    # the default tolerance (velocity_envelope) and a per-row shift, the same
    default = FR3.velocity_envelope_halves(q, JOINT_VELOCITY_LIMIT_TOLERANCE)
    upper, lower = FR3.velocity_envelope(q[1:2])
    np.testing.assert_array_equal(upper[0], default[1, :7])
    np.testing.assert_array_equal(lower[0], -default[1, 7:])
    widened = FR3.velocity_envelope_halves(q[1:2], np.full((1, 1), shift))
    np.testing.assert_array_equal(widened[0], batch[1])
