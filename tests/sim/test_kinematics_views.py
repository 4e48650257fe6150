"""sim/views.py gives MjData's rows as strided views where the layout allows (sim/arm.py,
sim/kinematics.py): the views select the rows the indices name."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.sim.views import strided_rows


def test_strided_rows_view_evenly_spaced_indices_and_refuse_others():
    a = np.arange(40.0).reshape(20, 2)
    index = np.array([[1, 2, 3], [7, 8, 9]])
    view = strided_rows(a, index)
    np.testing.assert_array_equal(view, a[index])
    view[1, 2] = -1.0  # a view: writes land in the array
    assert a[9].tolist() == [-1.0, -1.0]
    assert strided_rows(a, np.array([0, 1, 3])) is None  # uneven
    assert strided_rows(a, np.array([3, 2])) is None  # descending
    assert strided_rows(a, np.array([19, 20])) is None  # out of range
