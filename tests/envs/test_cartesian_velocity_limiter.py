"""libfranka's limitRate on twists (envs/cartesian_filters.py), batch-first: the limits of
include/franka/rate_limiting.h, jerk-limited ramps, conforming commands unchanged, and
libfranka's own outputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.envs import cartesian_filters as cart
from tests.cartesian_filter_helpers import (
    A_ROT,
    DT,
    J_ROT,
    LIMITS,
    RTOL,
    V_ROT,
    A,
    J,
    V,
    derivatives,
    row_norms,
    unit_vector,
)


def test_cartesian_limits_are_fr3_rate_limiting_h_values():
    assert LIMITS == pytest.approx((2.999, 8.999, 4499.999, 2.499, 16.999, 8499.999), abs=1e-12)


# --- Cartesian velocity limiter ------------------------------------------------------------


def _run_velocity(targets, steps):
    """Feed the limiter its own output, as the robot echoes O_dP_EE_c / O_ddP_EE_c."""
    n = targets(0).shape[0]
    v, a = np.zeros((n, 6)), np.zeros((n, 6))
    out = [v]
    for k in range(steps):
        v_new = cart.limit_rate_cartesian_velocity(targets(k), v, a, *LIMITS)
        a = (v_new - v) / DT
        v = v_new
        out.append(v)
    return np.stack(out)  # (steps + 1, n, 6)


def test_velocity_step_from_rest_gives_one_jerk_limited_increment():
    rng = np.random.default_rng(0)
    u, w = unit_vector(rng), unit_vector(rng)
    target = np.concatenate([u, w])[None]  # 1 m/s and 1 rad/s
    zero = np.zeros((1, 6))
    out = cart.limit_rate_cartesian_velocity(target, zero, zero, *LIMITS)[0]
    np.testing.assert_allclose(out[:3], J * DT * DT * u, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(out[3:], J_ROT * DT * DT * w, rtol=1e-14, atol=1e-18)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), magnitude=st.floats(4.0, 50.0))
def test_velocity_limiter_ramp_to_an_unreachable_target_respects_v_a_j(seed, magnitude):
    rng = np.random.default_rng(seed)
    target = magnitude * np.concatenate([unit_vector(rng), unit_vector(rng)])[None]
    v, a, j = derivatives(_run_velocity(lambda k: target, 1500)[:, 0])
    for half, (vm, am, jm) in ((slice(0, 3), (V, A, J)), (slice(3, 6), (V_ROT, A_ROT, J_ROT))):
        assert row_norms(v[:, half]).max() <= vm * (1 + RTOL)
        assert row_norms(a[:, half]).max() <= am * (1 + RTOL)
        assert row_norms(j[:, half]).max() <= jm * (1 + RTOL)
        # ...and it gets there: the velocity saturates at V along the target's direction.
        direction = target[0, half] / np.linalg.norm(target[0, half])
        np.testing.assert_allclose(v[-1, half], vm * direction, rtol=1e-12)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(0.1, 100.0))
def test_velocity_limiter_keeps_v_and_a_bounded_for_any_command_stream(seed, scale):
    # Erratic commands: velocity and acceleration stay bounded (the admissible step never
    # crosses the |v| = V sphere, and |a| <= A by construction). Jerk is not claimed here:
    # a sharp turn near |v| = V can shorten the acceleration by more than J dt.
    rng = np.random.default_rng(seed)
    commands = rng.normal(size=(600, 1, 6)) * scale
    v, a, _ = derivatives(_run_velocity(lambda k: commands[k], 600)[:, 0])
    for half, (vm, am) in ((slice(0, 3), (V, A)), (slice(3, 6), (V_ROT, A_ROT))):
        assert row_norms(v[:, half]).max() <= vm * (1 + RTOL)
        assert row_norms(a[:, half]).max() <= am * (1 + RTOL)


def test_velocity_limiter_converges_to_a_reachable_target_exactly():
    rng = np.random.default_rng(1)
    target = np.concatenate([0.5 * unit_vector(rng), 0.7 * unit_vector(rng)])[None]
    out = _run_velocity(lambda k: target, 400)[:, 0]
    np.testing.assert_array_equal(out[-50:], np.broadcast_to(target[0], (50, 6)))


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_velocity_command_within_reach_passes_unchanged(seed):
    # Small velocity, moderate acceleration, jerk below J, and far enough inside the
    # sphere that |a| <= J / A * distance: libfranka returns the command (to rounding).
    rng = np.random.default_rng(seed)
    v_last = rng.uniform(-0.3, 0.3, size=(1, 6))
    a_last = rng.uniform(-2.0, 2.0, size=(1, 6))
    jerk = rng.uniform(-1000.0, 1000.0, size=(1, 6))
    v_c = v_last + (a_last + jerk * DT) * DT
    out = cart.limit_rate_cartesian_velocity(v_c, v_last, a_last, *LIMITS)
    np.testing.assert_allclose(out, v_c, rtol=0, atol=1e-15)


def test_velocity_limiter_negligible_acceleration_returns_last_velocity_exactly():
    v_last = np.array([[0.2, -0.1, 0.3, 0.5, 0.0, -0.4]])
    zero = np.zeros((1, 6))
    with np.errstate(all="raise"):  # libfranka's 0/0 unit vector must not surface
        settled = cart.limit_rate_cartesian_velocity(v_last, v_last, zero, *LIMITS)
        # jerk 1e-14 > kNormEps, but the acceleration it integrates to, 1e-17, is not.
        nudged = cart.limit_rate_cartesian_velocity(zero + 1e-20, zero, zero, *LIMITS)
    np.testing.assert_array_equal(settled, v_last)
    np.testing.assert_array_equal(nudged, zero)


def test_velocity_limiter_outside_the_sphere_only_limits_jerk():
    # |v_last| > V and an acceleration perpendicular to it: the sqrt's argument is
    # negative, libfranka's NaN distance drops out of std::min, |a| passes unlimited.
    v_last = np.array([[0.0, 5.0, 0.0, 0.0, 0.0, 0.0]])
    a_last = np.array([[20.0, 0.0, 0.0, 0.0, 0.0, 0.0]])  # > A, kept (zero jerk)
    v_c = v_last + a_last * DT
    with np.errstate(all="raise"):
        out = cart.limit_rate_cartesian_velocity(v_c, v_last, a_last, *LIMITS)
    np.testing.assert_allclose(out, v_c, rtol=1e-15)
    assert np.isfinite(out).all()


def test_velocity_limiter_rows_and_per_robot_limits_are_independent():
    rng = np.random.default_rng(2)
    v_c, v_last, a_last = (rng.normal(size=(3, 6)) * s for s in (3.0, 1.0, 5.0))
    scale = np.array([1.0, 0.5, 2.0])
    limits = [lim * scale for lim in LIMITS]
    out = cart.limit_rate_cartesian_velocity(v_c, v_last, a_last, *limits)
    for i in range(3):
        single = cart.limit_rate_cartesian_velocity(
            v_c[i : i + 1], v_last[i : i + 1], a_last[i : i + 1], *(lim[i] for lim in limits)
        )
        np.testing.assert_array_equal(out[i], single[0])


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_velocity_limiter_rejects_non_finite_command(bad):
    zero = np.zeros((2, 6))
    v_c = zero.copy()
    v_c[1, 4] = bad
    with pytest.raises(ValueError, match="O_dP_EE_c is infinite or NaN."):
        cart.limit_rate_cartesian_velocity(v_c, zero, zero, *LIMITS)
    with pytest.raises(ValueError, match="twist_last"):
        cart.limit_rate_cartesian_velocity(zero, v_c, zero, *LIMITS)


# --- against libfranka itself ----------------------------------------------------------------
# Expected values: libfranka 0.21.2's src/rate_limiting.cpp and src/lowpass_filter.cpp built
# with Eigen 3.4.0 (g++ -O2) and called on the same inputs (wire arrays converted back).


@pytest.mark.parametrize(
    ("v_c", "v_last", "a_last", "expected"),
    [
        (
            [1.2, -0.4, 0.3, 0.5, 2.0, -1.0],
            [0.1, 0.2, -0.3, 0.4, -0.2, 0.1],
            [2.0, -1.0, 0.5, 3.0, 1.0, -2.0],
            [0.10556233046178545, 0.1970566157134704, -0.29755499352291404,
             0.4033351898699051, -0.1914012110935955, 0.09420578889530144],
        ),
        (  # both halves outside the sphere, accelerating sideways: only jerk-limited
            [0.01, 5.0, 0.0, 0.0, 0.0, 3.0],
            [0.0, 5.0, 0.0, 0.0, 0.0, 3.0],
            [20.0, 0.0, 0.0, 0.0, 30.0, 0.0],
            [0.015500001000000001, 5.0, 0.0, 0.0, 0.021500000999999998, 3.0],
        ),
        (  # just below V and braking hard toward it
            [2.9, 0.1, 0.0, 2.4, 0.0, 0.3],
            [2.95, 0.0, 0.0, 2.45, 0.0, 0.0],
            [8.0, 1.0, 0.0, 15.0, 2.0, 0.0],
            [2.955725269351488, 0.0048827299000470375, 0.0,
             2.463200134965355, 0.0019446195373955264, 0.008307069390671036],
        ),
    ],
)  # fmt: skip
def test_velocity_limiter_matches_libfranka(v_c, v_last, a_last, expected):
    out = cart.limit_rate_cartesian_velocity(
        np.array([v_c]), np.array([v_last]), np.array([a_last]), *LIMITS
    )
    np.testing.assert_allclose(out[0], expected, rtol=1e-13, atol=1e-16)
