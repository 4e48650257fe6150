"""ArmRows: every robot's rows of its own MjData, gathered into (n, ...) and written back,
through the C loops (sim/_rows.c) and the numpy ones alike."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from franka_sim_gym.sim import views
from franka_sim_gym.sim.views import ArmRows
from franka_sim_gym.sim.world import build_world


@pytest.mark.parametrize("kernel", [True, False])
def test_rows_gather_and_scatter_each_robots_own_mjdata(kernel, monkeypatch):
    if kernel and views.ROWS_KERNEL is None:
        pytest.skip("the C kernels are not built")
    if not kernel:
        monkeypatch.setattr(views, "ROWS_KERNEL", None)
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
