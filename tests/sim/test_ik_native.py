"""sim/_ik.c, the C replacement of ArmKinematics.solve (sim/ik.py's rule), held to the numpy
solve: the same verdicts, the same solutions to rounding (its 6x6 solve is an elimination
with partial pivoting where numpy calls LAPACK)."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.kinematics import IK_KERNEL, ArmKinematics
from franka_sim_gym.sim.rotations import rotation_exp
from franka_sim_gym.sim.world import HOME_Q

pytestmark = pytest.mark.skipif(IK_KERNEL is None, reason="the C kernels are not built / off")


def _kinematics(n: int, hand: bool = False):
    physics = ArmPhysics(n_arms=n, hand=hand)
    fast = ArmKinematics(physics.model, physics.layout)
    reference = ArmKinematics(physics.model, physics.layout, kernel=False)
    assert fast.native_solve is not None and reference.native_solve is None
    return fast, reference


def _assert_same_solution(a, b, atol: float) -> None:
    np.testing.assert_array_equal(a.converged, b.converged)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=atol)
    np.testing.assert_allclose(a.position_error, b.position_error, rtol=0, atol=atol)
    np.testing.assert_allclose(a.rotation_error, b.rotation_error, rtol=0, atol=atol)


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("with_tool", [False, True])
def test_the_c_solve_solves_as_the_numpy_solve(n: int, with_tool: bool):
    """Tracked targets (converged), far ones (capped steps), unreachable ones (unconverged
    after every iteration), held elbows and a subset of arms: the same verdicts, the
    same solutions to rounding."""
    fast, reference = _kinematics(n)
    rng = np.random.default_rng(n + 10 * with_tool)
    tool = None
    if with_tool:
        tool = np.tile(np.eye(4), (n, 1, 1))
        tool[:, :3, 3] = [0.0, 0.01, 0.1034]
        tool[:, :3, :3] = rotation_exp(np.tile([0.0, 0.0, -np.pi / 4], (n, 1)))
    q0 = np.tile(HOME_Q, (n, 1)) + rng.normal(size=(n, 7)) * 0.05
    seen = set()
    for trial in range(48):
        kind = trial % 6
        step = {0: 1e-3, 1: 1e-2, 2: 0.3, 3: 1e-3, 4: 1e-3, 5: 1e-3}[kind]
        target = reference.forward(q0 + rng.normal(size=(n, 7)) * step, tool)
        elbow = rows = None
        if kind == 2:
            target[n // 2, :3, 3] += [1.5, 0.0, 0.0]  # out of reach
        if kind in (3, 5):
            elbow = np.where(rng.random(n) < 0.5, q0[:, 2] + 0.01, np.nan)
        if kind in (4, 5):  # a subset of arms (5: some held elbows outside it)
            rows = rng.random(n) < 0.6
            rows[0] = False
        a = fast.solve(target, q0, tool, elbow, rows)
        b = reference.solve(target, q0, tool, elbow, rows)
        _assert_same_solution(a, b, 1e-11 if b.converged.all() else 1e-9)
        if elbow is not None:
            held = np.isfinite(elbow) & (np.ones(n, bool) if rows is None else rows)
            np.testing.assert_array_equal(a.q[held, 2], elbow[held])
        seen.add((kind, bool(b.converged.all())))
        if kind != 2 and b.converged.all():
            q0 = b.q
    assert (2, False) in seen and (0, True) in seen  # unconverged and converged both ran


def test_the_c_solve_keeps_forward_and_the_cache_right():
    """The C solve leaves MjData's rows at its last iterate, not the evaluation buffers:
    forward and jacobian afterwards, and a solve from a new start, still agree with the
    numpy solve."""
    fast, reference = _kinematics(3)
    q = np.tile(HOME_Q, (3, 1))
    target = reference.forward(q + 0.02)
    a = fast.solve(target, q)
    np.testing.assert_allclose(fast.forward(a.q), reference.forward(a.q), atol=1e-15)
    np.testing.assert_array_equal(fast.forward(q), reference.forward(q))
    np.testing.assert_array_equal(fast.jacobian(q), reference.jacobian(q))
    b, c = fast.solve(target, q), reference.solve(target, q)  # rows at q: cache hit
    _assert_same_solution(b, c, 1e-12)
    tool = np.tile(np.eye(4), (3, 1, 1))
    tool[:, 2, 3] = 0.2
    b, c = (
        fast.solve(reference.forward(q, tool), q, tool),
        reference.solve(reference.forward(q, tool), q, tool),
    )  # same q, another frame: the rows are re-evaluated
    _assert_same_solution(b, c, 1e-12)
    assert b.converged.all() and b.position_error.max() < 1e-12


def test_the_c_solve_refuses_bad_arguments_naming_them():
    n = 2
    fast, _ = _kinematics(n)
    q = np.tile(HOME_Q, (n, 1))
    solver = fast.native_solve
    args = [q, np.empty((n, 7)), fast.forward(q + 0.01), None, None, None, False, solver]
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


def test_without_mj_kinematics_from_c_the_numpy_solve_runs(monkeypatch):
    """Where MuJoCo's mj_kinematics cannot be had from C, solve takes the numpy rule."""
    from franka_sim_gym.sim import kinematics

    monkeypatch.setattr(kinematics, "mj_kinematics_addresses", lambda model, data: None)
    physics = ArmPhysics(n_arms=1)
    kin = ArmKinematics(physics.model, physics.layout)
    assert kin.native_solve is None
    q = np.tile(HOME_Q, (1, 1))
    target = kin.forward(q + 0.01)
    a = kin.solve(target, q)
    b = ArmKinematics(physics.model, physics.layout, kernel=False).solve(target, q)
    assert a.converged.all()
    np.testing.assert_array_equal(a.q, b.q)
