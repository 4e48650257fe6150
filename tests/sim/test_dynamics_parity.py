"""The arms' Jacobian at a point: its C replacement (sim/_dynamics.c) against numpy.

``jacobian_at`` is the rule the contact estimate, the load's weight, the Cartesian servo
and the numpy IK read; with the replacement loaded the trajectories must not change, so
the two must agree bit for bit (the sign of every zero included) on finite inputs: real
arm configurations (whose first axis is the base's z, so exact zeros are common) and
random ones with zeros and negative zeros planted.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.sim import dynamics
from franka_sim_gym.sim.arm import ArmPhysics

pytestmark = pytest.mark.skipif(dynamics.JACOBIAN_KERNEL is None, reason="sim._dynamics not built")


def _same(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_array_equal(a, b)
    assert np.array_equal(np.signbit(a), np.signbit(b))


def _both(monkeypatch, axes, anchors, point):
    with_kernel = dynamics.jacobian_at(axes, anchors, point)
    with monkeypatch.context() as m:
        m.setattr(dynamics, "JACOBIAN_KERNEL", None)
        with_numpy = dynamics.jacobian_at(axes, anchors, point)
    return with_kernel, with_numpy


@pytest.mark.parametrize("seed", range(8))
def test_random_axes_and_points_match_numpy_bit_for_bit(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 65))
    axes = rng.normal(size=(n, 7, 3))
    anchors = rng.normal(size=(n, 7, 3))
    point = rng.normal(size=(n, 3))
    for x in (axes, anchors):
        x[rng.random(x.shape) < 0.2] = 0.0
        x[rng.random(x.shape) < 0.1] = -0.0
    point[rng.random(point.shape) < 0.2] = 0.0
    anchors[:, 2] = point[:, None, :][:, 0]  # a lever of zeros
    _same(*_both(monkeypatch, axes, anchors, point))


@pytest.mark.parametrize("n", [1, 16])
def test_the_arms_jacobians_match_numpy_bit_for_bit(monkeypatch, n):
    rng = np.random.default_rng(n)
    physics = ArmPhysics(n_arms=n)
    physics.reset_arms(np.arange(n), rng.uniform(FR3.q_lower, FR3.q_upper, (n, 7)))
    mujoco.mj_forward(physics.model, physics.data)
    point = physics.flange_pose()[0]
    with_kernel = physics.jacobian(point)
    monkeypatch.setattr(dynamics, "JACOBIAN_KERNEL", None)
    _same(with_kernel, physics.jacobian(point))
    assert (with_kernel == 0.0).any()  # exact zeros were compared, with their signs


def test_out_is_filled_and_returned(monkeypatch):
    rng = np.random.default_rng(3)
    axes, anchors, point = (
        rng.normal(size=(2, 7, 3)),
        rng.normal(size=(2, 7, 3)),
        rng.normal(size=(2, 3)),
    )
    out = np.full((2, 6, 7), np.nan)
    assert dynamics.jacobian_at(axes, anchors, point, out=out) is out
    assert np.isfinite(out).all()
