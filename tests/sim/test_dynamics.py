"""The arms' Jacobian at a point (sim/dynamics.py jacobian_at, its one text sim/_dynamics.c)
against MuJoCo's own: ``mj_jac`` of the flange body at the same point, for one and 16
arms at random configurations."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.sim import dynamics
from franka_sim_gym.sim.arm import ArmPhysics


@pytest.mark.parametrize("n", [1, 16])
def test_the_arms_jacobians_are_mujocos(n):
    rng = np.random.default_rng(n)
    physics = ArmPhysics(n_arms=n)
    physics.reset_arms(np.arange(n), rng.uniform(FR3.q_lower, FR3.q_upper, (n, 7)))
    mujoco.mj_forward(physics.model, physics.data)
    point = physics.flange_pose()[0] + rng.normal(0, 0.05, (n, 3))  # a point off the flange
    J = physics.jacobian(point)
    model, lay = physics.model, physics.layout
    for i in range(n):
        data = physics.datas[i] if len(physics.datas) > 1 else physics.data
        world = point[i] + np.asarray(lay.base_pos[i])
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        body = model.site_bodyid[lay.flange_site[i]]
        mujoco.mj_jac(model, data, jacp, jacr, world, body)
        dofs = np.asarray(lay.dof_adr[i])
        np.testing.assert_allclose(J[i, :3], jacp[:, dofs], rtol=0, atol=1e-12)
        np.testing.assert_allclose(J[i, 3:], jacr[:, dofs], rtol=0, atol=1e-12)


def test_a_column_is_the_axis_crossed_with_the_lever_and_out_is_returned():
    axes = np.zeros((2, 7, 3))
    axes[:, :, 2] = 1.0  # every joint about z
    axes[1, 3] = [1.0, 0.0, 0.0]  # robot 1's joint 3 about x
    anchors = np.zeros((2, 7, 3))
    anchors[:, 5] = [0.1, 0.0, 0.0]
    point = np.array([[0.3, 0.2, 0.1], [0.0, 0.0, 0.5]])
    out = np.full((2, 6, 7), np.nan)
    assert dynamics.jacobian_at(axes, anchors, point, out=out) is out
    np.testing.assert_array_equal(out[0, :3, 0], [-0.2, 0.3, 0.0])  # z x (p - 0)
    np.testing.assert_array_equal(out[0, :3, 5], [-0.2, 0.3 - 0.1, 0.0])  # z x (p - (0.1, 0, 0))
    np.testing.assert_array_equal(out[1, :3, 3], [0.0, -0.5, 0.0])  # x x (0, 0, 0.5)
    np.testing.assert_array_equal(out[:, 3:], axes.transpose(0, 2, 1))
    with pytest.raises(ValueError, match="^point: axis 1 has length 2, expected 3"):
        dynamics.jacobian_at(axes, anchors, np.zeros((2, 2)), out)
