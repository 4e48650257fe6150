"""libfranka's cartesianLowpassFilter (envs/cartesian_filters.py), batch-first: the gain mix
of the translation, the rotation along the shorter arc, the rotation conversions it rests on,
and libfranka's own outputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.envs import cartesian_filters as cart
from franka_sim_gym.envs import client_filters as cf
from franka_sim_gym.sim.rotations import (
    quaternion_to_rotation,
    rotation_exp,
    rotation_log,
    rotation_to_quaternion,
)
from tests.cartesian_filter_helpers import (
    LIBFRANKA_LOWPASS_CASES,
    assert_rotation,
    homogeneous,
    random_pose,
    rotation_about,
    unit_vector,
)

# --- Cartesian low-pass filter ------------------------------------------------------------


def test_cartesian_lowpass_translation_is_the_100hz_gain_mix():
    T_c, T_ref = homogeneous(t=(1.0, -2.0, 0.5)), homogeneous(t=(0.0, 1.0, 0.25))
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], 100.0)[0]
    g = 0.385870  # docs/limits.md's table value at 100 Hz
    np.testing.assert_allclose(out[:3, 3], g * T_c[:3, 3] + (1 - g) * T_ref[:3, 3], atol=2e-6)
    np.testing.assert_allclose(out[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_array_equal(out[3], [0.0, 0.0, 0.0, 1.0])


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    angle=st.floats(1e-7, np.pi - 1e-3),
    cutoff=st.sampled_from([10.0, 30.0, 100.0, 500.0, 999.0]),
)
def test_cartesian_lowpass_rotates_gain_times_the_angle_about_the_same_axis(seed, angle, cutoff):
    rng = np.random.default_rng(seed)
    axis = unit_vector(rng)
    T_ref = random_pose(rng)
    T_c = homogeneous(rotation_about(axis, angle) @ T_ref[:3, :3], T_ref[:3, 3])
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], cutoff)[0]
    g = cf.lowpass_gain(cutoff)
    np.testing.assert_allclose(
        out[:3, :3], rotation_about(axis, g * angle) @ T_ref[:3, :3], atol=1e-12
    )
    assert_rotation(out[:3, :3])
    np.testing.assert_allclose(out[:3, 3], T_ref[:3, 3], atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_cartesian_lowpass_takes_the_shorter_arc_between_any_two_orientations(seed):
    rng = np.random.default_rng(seed)
    T_c, T_ref = random_pose(rng), random_pose(rng)
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], 50.0)[0]
    g = cf.lowpass_gain(50.0)
    step = rotation_log(T_c[:3, :3] @ T_ref[:3, :3].T)  # angle in [0, pi]
    expected = rotation_exp(g * step) @ T_ref[:3, :3]
    np.testing.assert_allclose(out[:3, :3], expected, atol=1e-10)
    assert_rotation(out[:3, :3])


def test_cartesian_lowpass_flips_the_quaternion_sign_for_the_shorter_arc():
    # Rot(z, 100 deg) and Rot(z, -100 deg): both traces are positive, so both quaternions
    # come out with w > 0 -- and their dot product is negative (cos 100 deg). The short
    # way from the reference is +160 deg, not -200 deg.
    z = np.array([0.0, 0.0, 1.0])
    R_ref, R_c = rotation_about(z, np.radians(100.0)), rotation_about(z, np.radians(-100.0))
    q_ref, q_c = rotation_to_quaternion(np.stack([R_ref, R_c]))
    assert q_ref[0] > 0 and q_c[0] > 0 and q_ref @ q_c < 0  # the case under test
    out = cart.cartesian_lowpass_filter(homogeneous(R_c)[None], homogeneous(R_ref)[None], 100.0)[0]
    g = cf.lowpass_gain(100.0)
    np.testing.assert_allclose(
        out[:3, :3], rotation_about(z, np.radians(100.0 + g * 160.0)), atol=1e-12
    )


def test_cartesian_lowpass_of_a_settled_pose_returns_it():
    rng = np.random.default_rng(3)
    T = np.stack([random_pose(rng) for _ in range(4)])
    with np.errstate(all="raise"):
        out = cart.cartesian_lowpass_filter(T, T, 100.0)
    np.testing.assert_allclose(out, T, atol=1e-15)


def test_cartesian_lowpass_nearly_equal_orientations_interpolate_linearly_without_nan():
    # 1e-9 rad apart: |q_ref . q_c| >= 1 - eps, Eigen's slerp takes the linear branch.
    rng = np.random.default_rng(4)
    T_ref = random_pose(rng)
    axis = unit_vector(rng)
    T_c = homogeneous(rotation_about(axis, 1e-9) @ T_ref[:3, :3], T_ref[:3, 3])
    with np.errstate(all="raise"):
        out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], 100.0)[0]
    assert_rotation(out[:3, :3], atol=1e-15)
    step = rotation_log(out[:3, :3] @ T_ref[:3, :3].T)
    np.testing.assert_allclose(step, cf.lowpass_gain(100.0) * 1e-9 * axis, atol=1e-15)


def test_cartesian_lowpass_per_robot_cutoff_and_rows_are_independent():
    rng = np.random.default_rng(5)
    T_c = np.stack([random_pose(rng) for _ in range(3)])
    T_ref = np.stack([random_pose(rng) for _ in range(3)])
    cutoffs = np.array([10.0, 100.0, 500.0])
    out = cart.cartesian_lowpass_filter(T_c, T_ref, cutoffs)
    for i in range(3):
        single = cart.cartesian_lowpass_filter(T_c[i : i + 1], T_ref[i : i + 1], cutoffs[i])
        np.testing.assert_allclose(out[i], single[0], atol=1e-15)


@pytest.mark.parametrize("cutoff", [0.0, -1.0, np.inf, np.nan])
def test_cartesian_lowpass_rejects_cutoff_not_positive_finite(cutoff):
    T = np.eye(4)[None]
    with pytest.raises(
        ValueError,
        match="Cartesian lowpass-filter: cutoff_frequency is zero, negative, infinite or NaN.",
    ):
        cart.cartesian_lowpass_filter(T, T, cutoff)
    # libfranka checks the cutoff before the signal.
    with pytest.raises(ValueError, match="cutoff_frequency"):
        cart.cartesian_lowpass_filter(np.full((1, 4, 4), np.nan), T, cutoff)


@pytest.mark.parametrize("which", ["T_c", "T_ref"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_cartesian_lowpass_rejects_non_finite_signal(which, bad):
    T = np.eye(4)[None]
    broken = T.copy()
    broken[0, 1, 3] = bad
    args = (broken, T) if which == "T_c" else (T, broken)
    msg = (
        "Cartesian lowpass-filter: current or past input value of the signal to be "
        "filtered is infinite or NaN."
    )
    with pytest.raises(ValueError, match=f"^{which}: {msg}"):
        cart.cartesian_lowpass_filter(*args, 100.0)


# --- rotations (Shepperd conversion, logarithm) -------------------------------------------


@settings(max_examples=100, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    angle=st.one_of(
        st.floats(0.0, np.pi),
        st.sampled_from([0.0, 1e-12, np.pi - 1e-6, np.pi - 1e-9, np.pi - 1e-12]),
    ),
)
def test_quaternion_round_trip_and_rotation_vector_are_exact_up_to_a_half_turn(seed, angle):
    rng = np.random.default_rng(seed)
    axis = unit_vector(rng)
    R = rotation_about(axis, angle)
    q = rotation_to_quaternion(R[None])[0]
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(quaternion_to_rotation(q[None])[0], R, atol=1e-15)
    rotvec = rotation_log(R[None])[0]
    if angle < np.pi - 1e-6:
        np.testing.assert_allclose(rotvec, angle * axis, atol=1e-13)
    else:  # a half turn: axis and -axis are the same rotation
        assert min(np.abs(rotvec - angle * axis).max(), np.abs(rotvec + angle * axis).max()) < 1e-8
    np.testing.assert_allclose(rotation_exp(rotvec), R, atol=1e-14)


# --- against libfranka itself ----------------------------------------------------------------
# Expected values: libfranka 0.21.2's src/rate_limiting.cpp and src/lowpass_filter.cpp built
# with Eigen 3.4.0 (g++ -O2) and called on the same inputs (wire arrays converted back).


@pytest.mark.parametrize(("T_c", "T_ref", "cutoff", "expected"), LIBFRANKA_LOWPASS_CASES)
def test_cartesian_lowpass_matches_libfranka(T_c, T_ref, cutoff, expected):
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], cutoff)
    np.testing.assert_allclose(out[0], expected, rtol=0, atol=1e-14)
