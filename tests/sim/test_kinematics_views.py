"""sim/views.py gives MjData's rows as strided views where the layout allows (sim/arm.py,
sim/kinematics.py): the views select the rows the indices name, and the gathering
fallback gives the same bits."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.kinematics import ArmKinematics
from franka_sim_gym.sim.views import strided_rows
from franka_sim_gym.sim.world import HOME_Q


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


@pytest.mark.parametrize("hand", [False, True])
def test_the_gathering_fallback_gives_the_same_bits(hand: bool):
    physics = ArmPhysics(n_arms=3, hand=hand)
    # (the numpy solve on both: the C solve needs the views)
    viewed = ArmKinematics(physics.model, physics.layout, kernel=False)
    gathered = ArmKinematics(physics.model, physics.layout, kernel=False)
    assert viewed._rows is not None
    gathered._rows = None
    rng = np.random.default_rng(4)
    q = np.tile(HOME_Q, (3, 1)) + rng.normal(scale=0.1, size=(3, 7))
    tool = np.tile(np.eye(4), (3, 1, 1))
    tool[1, :3, 3] = [0.01, -0.02, 0.1]
    for frame in (None, tool):
        np.testing.assert_array_equal(viewed.forward(q, frame), gathered.forward(q, frame))
        np.testing.assert_array_equal(viewed.jacobian(q, frame), gathered.jacobian(q, frame))
        target = viewed.forward(q + 0.01, frame)
        a, b = viewed.solve(target, q, frame), gathered.solve(target, q, frame)
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
        assert a.converged.all()
