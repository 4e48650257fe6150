"""sim/kinematics.py: forward kinematics equal to the physics' flange, the Jacobian, the IK."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.kinematics import ArmKinematics
from franka_sim_gym.sim.rotations import relative_rotation_log, rotation_exp, rotation_log
from franka_sim_gym.sim.world import HOME_Q


def _setup(n: int = 1):
    physics = ArmPhysics(n_arms=n)
    return physics, ArmKinematics(physics.model, physics.layout)


def test_forward_kinematics_is_the_physics_flange_pose():
    physics, kin = _setup(2)
    T = kin.forward(np.tile(HOME_Q, (2, 1)))
    p, R = physics.flange_pose()
    np.testing.assert_allclose(T[:, :3, 3], p, atol=1e-12)
    np.testing.assert_allclose(T[:, :3, :3], R, atol=1e-12)
    # docs/fr3-model.md
    np.testing.assert_allclose(T[0, :3, 3], [0.306891, 0.0, 0.590282], atol=1e-4)


def test_jacobian_matches_finite_differences_at_a_tool_frame():
    _, kin = _setup()
    tool = np.eye(4)[None].copy()
    tool[0, :3, 3] = [0.05, -0.02, 0.2]
    q = np.array([HOME_Q]) + 0.1
    J = kin.jacobian(q, tool)
    T = kin.forward(q, tool)
    eps = 1e-7
    for j in range(7):
        dq = np.zeros((1, 7))
        dq[0, j] = eps
        T2 = kin.forward(q + dq, tool)
        np.testing.assert_allclose((T2[0, :3, 3] - T[0, :3, 3]) / eps, J[0, :3, j], atol=1e-6)
        w = rotation_log(T[0, :3, :3].T @ T2[0, :3, :3]) / eps  # body frame
        np.testing.assert_allclose(T[0, :3, :3] @ w, J[0, 3:, j], atol=1e-6)


def test_ik_solves_a_reachable_pose_and_holds_the_elbow():
    _, kin = _setup()
    q0 = np.array([HOME_Q])
    target = kin.forward(q0)
    target[0, 0, 3] += 0.05
    r = kin.solve(target, q0, elbow=np.array([0.2]))
    assert r.converged[0]
    assert r.q[0, 2] == 0.2  # joint 3 held at the commanded elbow
    np.testing.assert_allclose(kin.forward(r.q)[0], target[0], atol=1e-7)


def test_ik_reports_an_unreachable_pose_as_not_converged():
    _, kin = _setup()
    q0 = np.array([HOME_Q])
    target = kin.forward(q0)
    target[0, 0, 3] += 2.0  # 2 m out: beyond the FR3's reach
    r = kin.solve(target, q0)
    assert not r.converged[0]
    assert r.position_error[0] > 0.5


def test_rotation_log_inverts_rotation_exp_up_to_pi():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(200, 3))
    v *= (rng.uniform(0.0, np.pi - 1e-3, size=200) / np.linalg.norm(v, axis=1))[:, None]
    v[:5] *= 1e-9
    np.testing.assert_allclose(rotation_log(rotation_exp(v)), v, atol=1e-12)
    np.testing.assert_allclose(
        rotation_log(rotation_exp(np.array([[0, 0, np.pi]]))), [[0, 0, np.pi]]
    )


def test_relative_rotation_log_is_the_log_of_the_relative_rotation():
    """log(R_a^T R_b) from the pair, without the product: the pose generator's
    angular velocity. Small, ordinary, exactly zero and near-pi relative angles."""
    rng = np.random.default_rng(3)
    R_a = rotation_exp(rng.normal(size=(6, 3)))
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.array([1e-9, 1e-4, 0.7, 2.5, np.pi - 1e-8, 0.0])
    R_b = R_a @ rotation_exp(axes * angles[:, None])
    got = relative_rotation_log(R_a, R_b)
    np.testing.assert_allclose(got, rotation_log(R_a.transpose(0, 2, 1) @ R_b), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), angles, atol=1e-7)
    assert not got[-1].any()


def test_forward_kinematics_follows_a_changed_tool_frame_at_the_same_q():
    """The evaluation cache is keyed on the EE frame as well as on q: after SetNEToEE
    moves the frame, the same joint positions give the new frame's pose."""
    physics = ArmPhysics(n_arms=1)
    kin = ArmKinematics(physics.model, physics.layout)
    q = HOME_Q[None].copy()
    tool = np.eye(4)[None].copy()
    tool[0, 2, 3] = 0.1
    flange = kin.forward(q)
    at_tool = kin.forward(q, tool)
    np.testing.assert_allclose(at_tool[0, :3, 3], flange[0, :3, 3] + 0.1 * flange[0, :3, 2])
    tool[0, 2, 3] = 0.2  # the same array, moved in place (as the state writer does)
    moved = kin.forward(q, tool)
    np.testing.assert_allclose(moved[0, :3, 3], flange[0, :3, 3] + 0.2 * flange[0, :3, 2])
    np.testing.assert_allclose(kin.forward(q)[0], flange[0])
