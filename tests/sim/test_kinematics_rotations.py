"""sim/rotations.py, the package's one rotation library: the logarithm up to a half turn
(its axis from the quaternion near pi), the polar factor the client reads its reference
pose through, and Eigen's quaternion conversions."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.rotations import (
    NEAR_PI,
    nearest_rotation,
    quaternion_to_rotation,
    rotation_exp,
    rotation_log,
    rotation_to_quaternion,
    skew,
)


def _axes(rng, n: int) -> np.ndarray:
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


@pytest.mark.parametrize("offset", [0.5, 2 * NEAR_PI, NEAR_PI / 2, 1e-6, 1e-9, 1e-12])
def test_rotation_log_keeps_the_axis_up_to_a_half_turn(offset: float):
    """Near pi the skew part 2 sin(angle) axis has lost its significant bits; the axis
    then comes from the quaternion and stays exact (up to the sign at pi itself)."""
    rng = np.random.default_rng(1)
    axes = _axes(rng, 50)
    angle = np.pi - offset
    # the relative rotation of two poses, as the pose limiter differentiates: products
    # round the skew part as a measured rotation does (rotation_exp's alone is exact)
    R_a = rotation_exp(rng.normal(size=(50, 3)))
    R_b = R_a @ rotation_exp(axes * angle)
    got = rotation_log(R_a.transpose(0, 2, 1) @ R_b)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), angle, rtol=0, atol=1e-7)
    direction = got / np.linalg.norm(got, axis=1, keepdims=True)
    aligned = direction * np.sign(np.einsum("ni,ni->n", direction, axes))[:, None]
    np.testing.assert_allclose(aligned, axes, rtol=0, atol=1e-12)


def test_nearest_rotation_is_the_polar_factor_of_a_float32_rotation():
    rng = np.random.default_rng(2)
    R = rotation_exp(rng.normal(size=(100, 3)) * 2.0)
    rounded = R.astype(np.float32).astype(np.float64)  # the wire state's O_T_EE_c
    X = nearest_rotation(rounded)
    eye = np.broadcast_to(np.eye(3), X.shape)
    np.testing.assert_allclose(X.transpose(0, 2, 1) @ X, eye, rtol=0, atol=1e-15)
    u, _, vt = np.linalg.svd(rounded)  # the polar factor by SVD
    np.testing.assert_allclose(X, u @ vt, rtol=0, atol=1e-14)
    np.testing.assert_allclose(X, R, rtol=0, atol=1e-7)


def test_quaternions_round_trip_through_every_branch_of_shepperds_method():
    """Rotations whose largest diagonal entry is the trace's, R00's, R11's and R22's:
    w > 0 first, then each axis's component."""
    rng = np.random.default_rng(3)
    R = np.concatenate(
        [rotation_exp(rng.normal(size=(20, 3)) * 0.3)]
        + [rotation_exp(np.eye(3)[k] * 3.0 + rng.normal(size=(20, 3)) * 0.05) for k in range(3)]
    )
    q = rotation_to_quaternion(R)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(quaternion_to_rotation(q), R, rtol=0, atol=1e-15)


def test_skew_is_the_cross_product():
    rng = np.random.default_rng(4)
    u, v = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    np.testing.assert_allclose((skew(u) @ v[..., None])[..., 0], np.cross(u, v), atol=1e-15)
