"""libfranka's limitRate on poses (envs/cartesian_filters.py), batch-first: jerk-limited
steps with the rotation factor, a near half turn, a far target within the limits, and
libfranka's own outputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.envs import cartesian_filters as cart
from franka_sim_gym.fci.frames import is_homogeneous
from franka_sim_gym.sim.rotations import rotation_exp, rotation_log
from tests.cartesian_filter_helpers import (
    A_ROT,
    DT,
    J_ROT,
    LIBFRANKA_POSE_LIMITER_CASES,
    LIMITS,
    POSE_FACTOR,
    RTOL,
    V_ROT,
    A,
    J,
    V,
    assert_rotation,
    derivatives,
    homogeneous,
    random_pose,
    rotation_about,
    row_norms,
    unit_vector,
)

# --- Cartesian pose limiter ----------------------------------------------------------------


def _twist_between(T0, T1):
    """The twist the limiter integrated from T0 to T1, (..., 6)."""
    v = (T1[..., :3, 3] - T0[..., :3, 3]) / DT
    w = rotation_log(T1[..., :3, :3] @ np.swapaxes(T0[..., :3, :3], -1, -2)) / DT
    return np.concatenate([v, w], axis=-1)


def _run_pose(T_start, T_target, steps):
    T, twist, dtwist = T_start, np.zeros((len(T_start), 6)), np.zeros((len(T_start), 6))
    out = [T]
    for _ in range(steps):
        T_new = cart.limit_rate_cartesian_pose(T_target, T, twist, dtwist, *LIMITS)
        twist_new = _twist_between(T, T_new)
        dtwist = (twist_new - twist) / DT
        twist, T = twist_new, T_new
        out.append(T)
    return np.stack(out)  # (steps + 1, n, 4, 4)


def test_pose_limiter_settled_pose_is_returned():
    rng = np.random.default_rng(0)
    T = np.stack([homogeneous(t=(0.3, 0.0, 0.5))] + [random_pose(rng) for _ in range(3)])
    zero = np.zeros((4, 6))
    with np.errstate(all="raise"):
        out = cart.limit_rate_cartesian_pose(T, T, zero, zero, *LIMITS)
    # Exactly for the identity orientation; otherwise R R^T is I only to rounding, and
    # that ~1e-16 rad "error" is a (tiny, allowed) command, as in libfranka.
    np.testing.assert_array_equal(out[0], T[0])
    np.testing.assert_allclose(out, T, rtol=0, atol=1e-15)


def test_pose_limiter_first_step_from_rest_is_jerk_limited_with_the_rotation_factor():
    rng = np.random.default_rng(1)
    T_last = random_pose(rng)
    u, axis = unit_vector(rng), unit_vector(rng)
    T_c = homogeneous(rotation_about(axis, 0.1) @ T_last[:3, :3], T_last[:3, 3] + 0.01 * u)
    zero = np.zeros((1, 6))
    out = cart.limit_rate_cartesian_pose(T_c[None], T_last[None], zero, zero, *LIMITS)[0]
    np.testing.assert_allclose(out[:3, 3] - T_last[:3, 3], J * DT**3 * u, rtol=1e-9)
    step = rotation_log(out[:3, :3] @ T_last[:3, :3].T)
    np.testing.assert_allclose(step, POSE_FACTOR * J_ROT * DT**3 * axis, rtol=1e-9)
    np.testing.assert_array_equal(out[3], [0.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize("offset", [1e-3, 1e-9, 0.0])
def test_pose_limiter_differentiates_a_near_half_turn_about_the_right_axis(offset):
    rng = np.random.default_rng(2)
    T_last = random_pose(rng)
    axis = unit_vector(rng)
    T_c = homogeneous(rotation_about(axis, np.pi - offset) @ T_last[:3, :3], T_last[:3, 3])
    zero = np.zeros((1, 6))
    with np.errstate(all="raise"):
        out = cart.limit_rate_cartesian_pose(T_c[None], T_last[None], zero, zero, *LIMITS)[0]
    step = rotation_log(out[:3, :3] @ T_last[:3, :3].T)
    expected = POSE_FACTOR * J_ROT * DT**3 * axis
    if offset == 0.0:  # exactly a half turn: either direction is the shortest
        assert min(np.abs(step - expected).max(), np.abs(step + expected).max()) < 1e-15
    else:
        np.testing.assert_allclose(step, expected, rtol=1e-6)


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_pose_limiter_far_target_stays_within_translational_and_scaled_rotational_limits(seed):
    rng = np.random.default_rng(seed)
    T0 = random_pose(rng)
    axis, direction = unit_vector(rng), unit_vector(rng)
    T_target = homogeneous(rotation_about(axis, 2.5) @ T0[:3, :3], T0[:3, 3] + 2.0 * direction)
    poses = _run_pose(T0[None], T_target[None], 1500)[:, 0]
    assert_rotation(poses[:, :3, :3], atol=1e-12)
    np.testing.assert_array_equal(poses[:, 3], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (1501, 4)))
    twists = _twist_between(poses[:-1], poses[1:])
    v, a, j = derivatives(twists)
    rot = (POSE_FACTOR * V_ROT, POSE_FACTOR * A_ROT, POSE_FACTOR * J_ROT)
    for half, (vm, am, jm) in ((slice(0, 3), (V, A, J)), (slice(3, 6), rot)):
        speed = row_norms(v[:, half])
        assert speed.max() <= vm * (1 + RTOL)
        assert speed.max() >= vm * (1 - RTOL)  # the limit, scaled by 0.99 for rotation, is hit
        assert row_norms(a[:, half]).max() <= am * (1 + RTOL)
        assert row_norms(j[:, half]).max() <= jm * (1 + RTOL)
    # On the way there (both still short of the target after 700 cycles) the motion
    # stays on the straight line / about the fixed axis. Later, oscillating about the
    # target (see the overshoot test), rounding off the line grows slowly -- as with
    # libfranka itself -- so the check stops here.
    approach = poses[:700]
    travelled = approach[:, :3, 3] - T0[:3, 3]
    assert (travelled @ direction).max() < 2.0
    np.testing.assert_allclose(np.cross(travelled, direction), 0.0, atol=1e-10)
    turned = rotation_log(approach[:, :3, :3] @ T0[:3, :3].T)
    assert row_norms(turned).max() < 2.5
    np.testing.assert_allclose(np.cross(turned, axis), 0.0, atol=1e-10)


def test_pose_limiter_is_no_trajectory_planner_a_step_target_overshoots():
    # The twist toward the target is (target - last) / dt: nothing plans the braking, so
    # at full speed the limiter runs past the target (as libfranka does; motion
    # generators must be smooth themselves).
    T0 = homogeneous()
    T_target = homogeneous(t=(1.0, 0.0, 0.0))
    x = _run_pose(T0[None], T_target[None], 1200)[:, 0, 0, 3]
    assert x.max() > 1.05


def test_pose_limiter_rows_are_independent_of_the_batch():
    rng = np.random.default_rng(3)
    T_last = np.stack([random_pose(rng) for _ in range(3)])
    T_c = np.stack(
        [
            homogeneous(rotation_exp(0.01 * rng.normal(size=3)) @ T[:3, :3], T[:3, 3] + 0.002)
            for T in T_last
        ]
    )
    twist, dtwist = rng.normal(size=(3, 6)) * 0.3, rng.normal(size=(3, 6)) * 2.0
    out = cart.limit_rate_cartesian_pose(T_c, T_last, twist, dtwist, *LIMITS)
    for i in range(3):
        row = slice(i, i + 1)
        single = cart.limit_rate_cartesian_pose(
            T_c[row], T_last[row], twist[row], dtwist[row], *LIMITS
        )
        np.testing.assert_array_equal(out[i], single[0])
    assert_rotation(out[:, :3, :3])


def test_pose_limiter_rejects_non_finite_then_invalid_transforms():
    T = np.eye(4)[None]
    zero = np.zeros((1, 6))
    nan = T.copy()
    nan[0, 0, 0] = np.nan  # also not a valid rotation: the finite check comes first
    with pytest.raises(ValueError, match="O_T_EE_c is infinite or NaN."):
        cart.limit_rate_cartesian_pose(nan, T, zero, zero, *LIMITS)
    for broken in (
        np.diag([1.0, 1.0, 1.1, 1.0]),
        homogeneous(t=(1, 2, 3)).T,
    ):  # scaled / transposed
        with pytest.raises(
            ValueError, match="O_T_EE_c is invalid transformation matrix. Has to be column major!"
        ):
            cart.limit_rate_cartesian_pose(broken[None], T, zero, zero, *LIMITS)
    # Within libfranka's 1e-5 tolerance a slightly denormalised rotation is accepted, and
    # the limiter's output (built from a unit quaternion) is homogeneous again.
    out = cart.limit_rate_cartesian_pose(
        np.diag([1.0, 1.0, 1.0 + 5e-6, 1.0])[None], T, zero, zero, *LIMITS
    )
    assert is_homogeneous(out, 1e-9).all()
    with pytest.raises(ValueError, match="T_last"):
        cart.limit_rate_cartesian_pose(T, nan, zero, zero, *LIMITS)


# --- against libfranka itself ----------------------------------------------------------------
# Expected values: libfranka 0.21.2's src/rate_limiting.cpp and src/lowpass_filter.cpp built
# with Eigen 3.4.0 (g++ -O2) and called on the same inputs (wire arrays converted back).


@pytest.mark.parametrize(
    ("T_c", "T_last", "twist", "dtwist", "expected"), LIBFRANKA_POSE_LIMITER_CASES
)
def test_pose_limiter_matches_libfranka(T_c, T_last, twist, dtwist, expected):
    out = cart.limit_rate_cartesian_pose(
        T_c[None], T_last[None], np.array([twist]), np.array([dtwist]), *LIMITS
    )
    np.testing.assert_allclose(out[0], expected, rtol=0, atol=1e-14)
