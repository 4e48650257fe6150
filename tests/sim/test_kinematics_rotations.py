"""sim/rotations.py, the package's one rotation library: the logarithm up to a half turn
(its axis from the quaternion near pi), the polar factor the client reads its reference
pose through, and Eigen's quaternion conversions."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.rotations import (
    NEAR_PI,
    SERIES_BELOW,
    nearest_rotation,
    quaternion_slerp,
    quaternion_to_rotation,
    relative_rotation_log,
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


def test_rotation_exp_is_rodrigues_and_its_series_below_the_threshold():
    rng = np.random.default_rng(5)
    rotvec = _axes(rng, 20) * rng.uniform(0.1, 3.0, (20, 1))
    R = rotation_exp(rotvec)
    angle = np.linalg.norm(rotvec, axis=1)
    K = skew(rotvec / angle[:, None])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    np.testing.assert_allclose(R, np.eye(3) + s * K + (1 - c) * (K @ K), rtol=0, atol=1e-15)
    np.testing.assert_allclose(rotation_log(R), rotvec, rtol=0, atol=1e-15)
    # Below SERIES_BELOW: I + K + K^2 / 2 (K = skew(rotvec)). Off the diagonal K^2's term
    # (~1e-17) sits far above the rounding of K's (~1e-8 * 1e-16), so a relative
    # tolerance sees both coefficients.
    tiny = _axes(rng, 5) * SERIES_BELOW / 2
    Kt = skew(tiny)
    series = np.eye(3) + Kt + 0.5 * (Kt @ Kt)
    off = ~np.eye(3, dtype=bool)
    np.testing.assert_allclose(rotation_exp(tiny)[:, off], series[:, off], rtol=1e-12, atol=0)


def test_relative_rotation_log_is_the_log_of_the_relative_rotation():
    rng = np.random.default_rng(6)
    R_a = rotation_exp(rng.normal(size=(30, 3)))
    w = _axes(rng, 30) * rng.uniform(0.0, np.pi - 2 * NEAR_PI, (30, 1))
    R_b = R_a @ rotation_exp(w)
    out = np.full((30, 3), np.nan)
    got = relative_rotation_log(R_a, R_b, out=out)
    assert got is out
    np.testing.assert_allclose(got, w, rtol=0, atol=1e-14)


def test_slerp_takes_the_shorter_arc_and_is_linear_for_one_rotation():
    z = np.array([0.0, 0.0, 1.0])
    q0 = rotation_to_quaternion(rotation_exp(z * 0.2))
    q1 = -rotation_to_quaternion(rotation_exp(z * 1.0))  # the same rotation, other sign
    q = quaternion_slerp(q0, q1, 0.25)
    np.testing.assert_allclose(rotation_log(quaternion_to_rotation(q)), z * 0.4, atol=1e-15)
    # |q0 . q0| = 1: Eigen's linear branch, (1 - t) q0 + t q0
    np.testing.assert_array_equal(quaternion_slerp(q0, q0, 0.3), 0.7 * q0 + 0.3 * q0)


def test_a_rows_result_is_the_same_in_any_batch_and_under_leading_axes():
    """One text, one rotation at a time: a row's bits do not depend on the rows beside it
    (numpy's vectorised logarithm gave 192 of these 2,000 rows other last bits alone than
    in the batch), and (..., 3) leading axes are rows."""
    rng = np.random.default_rng(7)
    rotvec = rng.normal(size=(2000, 3))
    R = rotation_exp(rotvec)
    R_b = rotation_exp(rng.normal(size=(2000, 3)))
    q = rotation_to_quaternion(R)
    rounded = R.astype(np.float32).astype(np.float64)
    log, relative = rotation_log(R), relative_rotation_log(R, R_b)
    for i in range(2000):
        np.testing.assert_array_equal(rotation_log(R[i]), log[i])
        np.testing.assert_array_equal(
            relative_rotation_log(R[i : i + 1], R_b[i : i + 1])[0], relative[i]
        )
    for i in (0, 17, 1999):
        np.testing.assert_array_equal(rotation_exp(rotvec[i]), R[i])
        np.testing.assert_array_equal(rotation_to_quaternion(R[i]), q[i])
        np.testing.assert_array_equal(quaternion_to_rotation(q[i]), quaternion_to_rotation(q)[i])
        np.testing.assert_array_equal(nearest_rotation(rounded[i]), nearest_rotation(rounded)[i])
    np.testing.assert_array_equal(rotation_exp(rotvec.reshape(40, 50, 3)), R.reshape(40, 50, 3, 3))
    np.testing.assert_array_equal(rotation_log(R.reshape(40, 50, 3, 3)), log.reshape(40, 50, 3))


@pytest.mark.parametrize(
    ("call", "bad"),
    [
        (rotation_log, np.zeros((2, 3, 4))),
        (rotation_exp, np.zeros((2, 4))),
        (quaternion_to_rotation, np.zeros(3)),
        (nearest_rotation, np.zeros(9)),
    ],
)
def test_an_array_of_the_wrong_shape_is_a_clear_error(call, bad):
    with pytest.raises(ValueError, match=r"expected an array of shape \(\.\.\., "):
        call(bad)
