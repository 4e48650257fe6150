"""The lost-cycle laws (docs/fci-behaviour.md "What the sim does with a lost cycle"), including the
Cartesian
ones the Cartesian generators will use."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci import extrapolation as ex

DT = 1e-3


def test_q_c_law_is_semi_implicit_euler_at_frozen_acceleration():
    q, v, a = np.array([[0.1]]), np.array([[0.2]]), np.array([[3.0]])
    q1, v1 = ex.position_step(q, v, a)
    assert v1[0, 0] == pytest.approx(0.2 + 3.0 * DT)
    assert q1[0, 0] == pytest.approx(0.1 + (0.2 + 3.0 * DT) * DT)  # v first, then q


def test_dq_c_and_twist_law_has_no_jerk_term():
    v = np.array([[0.5, -0.1, 0.0, 0.2, 0.0, 0.0]])
    a = np.array([[1.0, 0.0, 2.0, 0.0, -3.0, 0.0]])
    for _ in range(19):
        v = ex.velocity_step(v, a)
    np.testing.assert_allclose(v, [[0.519, -0.1, 0.038, 0.2, -0.057, 0.0]], atol=1e-12)


def test_pose_law_translates_per_axis_and_rotates_on_the_right_by_the_axis_angle_increment():
    T = np.tile(np.eye(4), (2, 1, 1))
    T[1, :3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # arm 1 starts yawed 90 degrees
    v = np.array([[0.1, 0.0, 0.0]] * 2)
    a = np.array([[0.0, 2.0, 0.0]] * 2)
    omega = np.array([[0.0, 0.0, 1.0]] * 2)
    alpha = np.array([[0.0, 0.0, 10.0]] * 2)
    for _ in range(10):
        T, v, omega = ex.pose_step(T, v, a, omega, alpha)
    # about z: angle = sum_k (1 + 10 k dt) dt for k = 1..10
    angle = sum((1.0 + 10.0 * k * DT) * DT for k in range(1, 11))
    c, s = np.cos(angle), np.sin(angle)
    np.testing.assert_allclose(T[0, :3, :3], [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-12)
    # composed on the right: the start orientation times the increment
    np.testing.assert_allclose(
        T[1, :3, :3], np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]]) @ T[0, :3, :3], atol=1e-12
    )
    # translation: x at constant velocity, y at constant acceleration (semi-implicit sums)
    assert T[0, 0, 3] == pytest.approx(0.1 * 10 * DT)
    assert T[0, 1, 3] == pytest.approx(sum(2.0 * k * DT * DT for k in range(1, 11)))
    np.testing.assert_allclose(T[:, 3], [[0, 0, 0, 1]] * 2)
    assert omega[0, 2] == pytest.approx(1.0 + 10 * 10.0 * DT)


def test_elbow_law_moves_the_angle_and_holds_the_branch_flag():
    elbow = np.array([[0.3, -1.0]])
    e, v = ex.elbow_step(elbow, np.array([0.5]), np.array([1.0]))
    assert e[0, 1] == -1.0
    assert e[0, 0] == pytest.approx(0.3 + (0.5 + 1e-3) * DT)
    assert v[0] == pytest.approx(0.5 + 1e-3)


def test_the_laws_take_one_shape_and_name_the_array_that_differs():
    x, v, a = np.array([0.1, 0.2]), np.array([1.0, -1.0]), np.array([2.0, 0.0])
    x1, v1 = ex.position_step(x, v, a)
    np.testing.assert_array_equal(v1, v + a * DT)
    np.testing.assert_array_equal(x1, x + (v + a * DT) * DT)
    with pytest.raises(ValueError, match="a: axis 0 has length 3, expected 2"):
        ex.position_step(x, v, np.zeros(3))
    with pytest.raises(ValueError, match="a: axis 1 has length 6, expected 3"):
        ex.velocity_step(np.zeros((2, 3)), np.zeros((2, 6)))
