"""ArmRows: every robot's rows of its own MjData, gathered into (n, ...) and written back,
through the C loops (sim/_rows.c) and, for rows that are not views, numpy's."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from franka_sim_gym.fci.config import ControllerConfig
from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.sim import views
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.dynamics import ArmDynamics
from franka_sim_gym.sim.views import ArmRows, Gathering
from franka_sim_gym.sim.world import build_world


@pytest.mark.parametrize("as_views", [True, False])
def test_rows_gather_and_scatter_each_robots_own_mjdata(as_views, monkeypatch):
    if not as_views:  # rows the C loops cannot take: copied by numpy
        monkeypatch.setattr(views, "strided_rows", lambda array, index: None)
    model, layout = build_world(1, hand=True)
    datas = [mujoco.MjData(model) for _ in range(4)]
    rng = np.random.default_rng(0)
    for d in datas:
        d.qpos[:] = rng.normal(size=model.nq)
        mujoco.mj_kinematics(model, d)
    q = ArmRows([d.qpos for d in datas], layout.qpos_adr[0])
    np.testing.assert_array_equal(q.gather(), [d.qpos[layout.qpos_adr[0]] for d in datas])
    site = ArmRows([d.site_xmat for d in datas], layout.flange_site[0])
    assert site.gather().shape == (4, 9)
    np.testing.assert_array_equal(site.out[3], datas[3].site_xmat[layout.flange_site[0]])
    ctrl = ArmRows([d.ctrl for d in datas], layout.actuator_ids[0])
    values = rng.normal(size=(2, 7))
    ctrl.scatter(values, np.array([3, 1]))
    np.testing.assert_array_equal(datas[3].ctrl[:7], values[0])
    np.testing.assert_array_equal(datas[1].ctrl[:7], values[1])
    assert not datas[0].ctrl.any() and not datas[2].ctrl.any()
    ctrl.scatter(np.ones((4, 7)))
    assert all(np.all(d.ctrl[:7] == 1.0) for d in datas)


@pytest.mark.parametrize("as_views", [True, False])
def test_gathering_refreshes_every_slice_of_every_robot(as_views, monkeypatch):
    if not as_views:  # rows the C loops cannot take: copied by numpy
        monkeypatch.setattr(views, "strided_rows", lambda array, index: None)
    model, layout = build_world(1, hand=True)
    datas = [mujoco.MjData(model) for _ in range(3)]
    q = ArmRows([d.qpos for d in datas], layout.qpos_adr[0])
    mat = ArmRows([d.site_xmat for d in datas], layout.flange_site[0])
    gathering = Gathering([q, mat])
    rng = np.random.default_rng(1)
    for _ in range(2):  # the same buffers, refreshed in place every time
        for d in datas:
            d.qpos[:] = rng.normal(size=model.nq)
            mujoco.mj_kinematics(model, d)
        gathering.gather()
        np.testing.assert_array_equal(q.out, [d.qpos[layout.qpos_adr[0]] for d in datas])
        np.testing.assert_array_equal(mat.out, [d.site_xmat[layout.flange_site[0]] for d in datas])


def test_the_model_terms_are_those_of_the_state_just_reached():
    """The rows the arms gather after each step (sim/dynamics.py model_rows): M, the bias
    forces and the Jacobian of the new state, as read from every arm's own MjData."""
    physics = ArmPhysics(n_arms=2)
    dynamics = ArmDynamics(physics)
    # the contact sensing's plan reads them (fci/contact/_contact.c Sensing): built at the
    # home state, then restarted at the state the steps reach, its model terms are these
    sensing = FciController(physics, ControllerConfig()).contact
    q = physics.q.copy()
    q[:, 3] += 0.05
    for _ in range(3):
        physics.step(q, None)
    lay = physics.layout
    dofs = np.asarray(lay.dof_adr[0])
    sensing.reset([0, 1])
    for i, d in enumerate(physics.datas):
        full = np.zeros((physics.model.nv, physics.model.nv))
        mujoco.mj_fullM(physics.model, d, full)
        np.testing.assert_array_equal(sensing.estimator.mass[i], full[np.ix_(dofs, dofs)])
        np.testing.assert_array_equal(
            sensing.estimator.bias[i], d.qfrc_bias[dofs] - d.qfrc_passive[dofs]
        )
        joints = physics.model.dof_jntid[dofs]
        axes = dynamics.jacobian(physics.flange_pose()[0])[i, 3:]
        np.testing.assert_array_equal(axes, d.xaxis[joints].T)


def test_a_planned_gathering_refuses_rows_that_do_not_fit_naming_them():
    out = np.zeros((2, 7))
    with pytest.raises(ValueError, match="2 sources for 3 rows"):
        views.ROWS_KERNEL.Gathers((((np.zeros(7), np.zeros(7)), np.zeros((3, 7))),))
    with pytest.raises(ValueError, match="sources\\[i\\]: expected 7 float64 values"):
        views.ROWS_KERNEL.Gathers((((np.zeros(7), np.zeros(6)), out),))
    with pytest.raises(ValueError, match="out: expected a C-contiguous writable float64"):
        views.ROWS_KERNEL.Gathers((((np.zeros(7), np.zeros(7)), out.T),))
    with pytest.raises(TypeError, match="each pair must be"):
        views.ROWS_KERNEL.Gathers(((np.zeros(7), out, 1),))
