"""The IK solve (sim/kinematics.py ArmKinematics.solve; its one text sim/_ik.c and
native/_ik_core.h): tracked targets reached to the tolerance in MuJoCo's own forward
kinematics, held elbows kept exactly, arms outside ``rows`` left at their start,
unreachable targets reported unconverged, a far target's step capped at MAX_STEP, and bad
arguments named."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim import kinematics
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.ik import MAX_STEP
from franka_sim_gym.sim.kinematics import IK_KERNEL, ArmKinematics
from franka_sim_gym.sim.rotations import relative_rotation_log, rotation_exp
from franka_sim_gym.sim.world import HOME_Q


def _kinematics(n: int, **settings) -> ArmKinematics:
    physics = ArmPhysics(n_arms=n)
    return ArmKinematics(physics.model, physics.layout, **settings)


def _tool(n: int) -> np.ndarray:
    tool = np.tile(np.eye(4), (n, 1, 1))
    tool[:, :3, 3] = [0.0, 0.01, 0.1034]
    tool[:, :3, :3] = rotation_exp(np.tile([0.0, 0.0, -np.pi / 4], (n, 1)))
    return tool


def _pose_errors(kin, q, target, tool):
    T = kin.forward(q, tool)
    position = np.linalg.norm(T[:, :3, 3] - target[:, :3, 3], axis=1)
    rotation = np.linalg.norm(relative_rotation_log(T[:, :3, :3], target[:, :3, :3]), axis=1)
    return position, rotation


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("with_tool", [False, True])
def test_the_solve_reaches_tracked_targets_holds_elbows_and_leaves_other_arms(n, with_tool):
    kin = _kinematics(n)
    rng = np.random.default_rng(n + 10 * with_tool)
    tool = _tool(n) if with_tool else None
    q0 = np.tile(HOME_Q, (n, 1)) + rng.normal(size=(n, 7)) * 0.05
    for trial in range(24):
        kind = trial % 4
        target = kin.forward(q0 + rng.normal(size=(n, 7)) * 1e-3, tool)
        elbow = rows = None
        if kind in (1, 3):
            elbow = np.where(rng.random(n) < 0.5, q0[:, 2] + 1e-4, np.nan)
        if kind in (2, 3):  # a subset of arms (3: some held elbows outside it)
            rows = rng.random(n) < 0.6
            rows[0] = False
        result = kin.solve(target, q0, tool, elbow, rows)
        active = np.ones(n, bool) if rows is None else rows
        np.testing.assert_array_equal(result.q[~active], q0[~active])  # untouched
        assert result.converged.all()  # (arms outside rows count as converged)
        position, rotation = _pose_errors(kin, result.q, target, tool)
        free = active & (np.ones(n, bool) if elbow is None else ~np.isfinite(elbow))
        assert position[free].max(initial=0) < 1e-7 and rotation[free].max(initial=0) < 1e-7
        np.testing.assert_allclose(result.position_error[free], position[free], atol=1e-9)
        np.testing.assert_allclose(result.rotation_error[free], rotation[free], atol=1e-9)
        if elbow is not None:
            held = np.isfinite(elbow) & active
            np.testing.assert_array_equal(result.q[held, 2], elbow[held])
        q0 = result.q


def test_an_unreachable_target_is_unconverged_and_a_far_one_steps_at_most_max_step():
    kin = _kinematics(2)
    q = np.tile(HOME_Q, (2, 1))
    target = kin.forward(q)
    target[1, :3, 3] += [1.5, 0.0, 0.0]  # out of reach
    result = kin.solve(target, q)
    np.testing.assert_array_equal(result.converged, [True, False])
    assert result.position_error[1] > 0.5 and result.position_error[0] < 1e-7
    position, rotation = _pose_errors(kin, result.q, target, None)
    np.testing.assert_allclose(result.position_error, position, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(result.rotation_error, rotation, rtol=1e-6, atol=1e-12)
    one_step = _kinematics(1, max_iterations=1)
    far = one_step.forward(q[:1] + 1.5)
    stepped = one_step.solve(far, q[:1]).q
    assert np.abs(stepped - q[:1]).max() == pytest.approx(MAX_STEP, rel=1e-12)


def test_forward_and_the_cache_stay_right_after_a_solve():
    """The C solve leaves MjData's rows at its last iterate, not the evaluation buffers:
    forward and jacobian afterwards are those of a fresh solver, and a solve at the same
    q in another frame re-evaluates."""
    kin, fresh = _kinematics(3), _kinematics(3)
    q = np.tile(HOME_Q, (3, 1))
    a = kin.solve(fresh.forward(q + 0.02), q)
    np.testing.assert_array_equal(kin.forward(a.q), fresh.forward(a.q))
    np.testing.assert_array_equal(kin.forward(q), fresh.forward(q))
    np.testing.assert_array_equal(kin.jacobian(q), fresh.jacobian(q))
    tool = np.tile(np.eye(4), (3, 1, 1))
    tool[:, 2, 3] = 0.2
    b = kin.solve(fresh.forward(q, tool), q, tool)  # same q, another frame
    assert b.converged.all() and b.position_error.max() < 1e-12


def test_the_c_solve_refuses_bad_arguments_naming_them():
    n = 2
    kin = _kinematics(n)
    q = np.tile(HOME_Q, (n, 1))
    solver = kin.native_solve
    args = [q, np.empty((n, 7)), kin.forward(q + 0.01), None, None, None, False, solver]
    assert IK_KERNEL.ik_solve(*args) is None
    bad = {
        0: ("q_init", q.astype(np.float32)),
        1: ("q", np.zeros((n, 6))),
        2: ("target", np.zeros((n, 3, 4))),
        3: ("F_T_EE", np.zeros((n, 4))),
        4: ("elbow", np.zeros(n + 1)),
        5: ("active", np.ones(n + 1, dtype=bool)),
    }
    for k, (name, value) in bad.items():
        broken = list(args)
        broken[k] = value
        with pytest.raises(ValueError, match=f"^{name}: "):
            IK_KERNEL.ik_solve(*broken)
    broken = list(args)
    broken[7] = (*solver[:14], 7)  # the elbow joint comes from sim/ik.py, checked
    with pytest.raises(ValueError, match="^elbow_joint: "):
        IK_KERNEL.ik_solve(*broken)


def test_without_mj_kinematics_from_c_the_solver_refuses_to_start(monkeypatch):
    monkeypatch.setattr(kinematics, "mj_kinematics_addresses", lambda model, data: None)
    with pytest.raises(RuntimeError, match="mj_kinematics cannot be called from sim/_ik.c"):
        _kinematics(1)
