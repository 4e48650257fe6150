"""libfranka's Cartesian client-side filters (cartesianLowpassFilter, the twist and pose
overloads of limitRate), batch-first."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.envs import cartesian_filters as cart
from franka_sim_gym.envs import client_filters as cf
from franka_sim_gym.fci.frames import is_homogeneous
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.sim.rotations import (
    quaternion_to_rotation,
    rotation_exp,
    rotation_log,
    rotation_to_quaternion,
)

DT = 1e-3
#: kMaxTranslational* / kMaxRotational* (include/franka/rate_limiting.h): limit - 1e-3.
V, A, J = FR3.v_trans_max, FR3.a_trans_max, FR3.j_trans_max
V_ROT, A_ROT, J_ROT = FR3.v_rot_max, FR3.a_rot_max, FR3.j_rot_max
LIMITS = (V, A, J, V_ROT, A_ROT, J_ROT)
#: kFactorCartesianRotationPoseInterface: the pose overload scales the rotational limits.
POSE_FACTOR = 0.99
#: Differencing a float64 stream at 1 kHz twice costs ~1e-11 relative.
RTOL = 1e-8


def _unit(rng, size=3):
    u = rng.normal(size=size)
    return u / np.linalg.norm(u)


def _pose(R=None, t=(0.0, 0.0, 0.0)):
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = t
    return T


def _random_pose(rng):
    return _pose(rotation_exp(rng.normal(size=3)), rng.normal(size=3))


def _rot(axis, angle):
    return rotation_exp(np.asarray(axis, dtype=float) * angle)


def _norms(x):
    return np.linalg.norm(x, axis=-1)


def _assert_rotation(R, atol=1e-12):
    R = np.asarray(R)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=atol
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=atol)


def test_cartesian_limits_are_fr3_rate_limiting_h_values():
    assert LIMITS == pytest.approx((2.999, 8.999, 4499.999, 2.499, 16.999, 8499.999), abs=1e-12)


# --- Cartesian low-pass filter ------------------------------------------------------------


def test_cartesian_lowpass_translation_is_the_100hz_gain_mix():
    T_c, T_ref = _pose(t=(1.0, -2.0, 0.5)), _pose(t=(0.0, 1.0, 0.25))
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
    axis = _unit(rng)
    T_ref = _random_pose(rng)
    T_c = _pose(_rot(axis, angle) @ T_ref[:3, :3], T_ref[:3, 3])
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], cutoff)[0]
    g = cf.lowpass_gain(cutoff)
    np.testing.assert_allclose(out[:3, :3], _rot(axis, g * angle) @ T_ref[:3, :3], atol=1e-12)
    _assert_rotation(out[:3, :3])
    np.testing.assert_allclose(out[:3, 3], T_ref[:3, 3], atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_cartesian_lowpass_takes_the_shorter_arc_between_any_two_orientations(seed):
    rng = np.random.default_rng(seed)
    T_c, T_ref = _random_pose(rng), _random_pose(rng)
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], 50.0)[0]
    g = cf.lowpass_gain(50.0)
    step = rotation_log(T_c[:3, :3] @ T_ref[:3, :3].T)  # angle in [0, pi]
    expected = rotation_exp(g * step) @ T_ref[:3, :3]
    np.testing.assert_allclose(out[:3, :3], expected, atol=1e-10)
    _assert_rotation(out[:3, :3])


def test_cartesian_lowpass_flips_the_quaternion_sign_for_the_shorter_arc():
    # Rot(z, 100 deg) and Rot(z, -100 deg): both traces are positive, so both quaternions
    # come out with w > 0 -- and their dot product is negative (cos 100 deg). The short
    # way from the reference is +160 deg, not -200 deg.
    z = np.array([0.0, 0.0, 1.0])
    R_ref, R_c = _rot(z, np.radians(100.0)), _rot(z, np.radians(-100.0))
    q_ref, q_c = rotation_to_quaternion(np.stack([R_ref, R_c]))
    assert q_ref[0] > 0 and q_c[0] > 0 and q_ref @ q_c < 0  # the case under test
    out = cart.cartesian_lowpass_filter(_pose(R_c)[None], _pose(R_ref)[None], 100.0)[0]
    g = cf.lowpass_gain(100.0)
    np.testing.assert_allclose(out[:3, :3], _rot(z, np.radians(100.0 + g * 160.0)), atol=1e-12)


def test_cartesian_lowpass_of_a_settled_pose_returns_it():
    rng = np.random.default_rng(3)
    T = np.stack([_random_pose(rng) for _ in range(4)])
    with np.errstate(all="raise"):
        out = cart.cartesian_lowpass_filter(T, T, 100.0)
    np.testing.assert_allclose(out, T, atol=1e-15)


def test_cartesian_lowpass_nearly_equal_orientations_interpolate_linearly_without_nan():
    # 1e-9 rad apart: |q_ref . q_c| >= 1 - eps, Eigen's slerp takes the linear branch.
    rng = np.random.default_rng(4)
    T_ref = _random_pose(rng)
    axis = _unit(rng)
    T_c = _pose(_rot(axis, 1e-9) @ T_ref[:3, :3], T_ref[:3, 3])
    with np.errstate(all="raise"):
        out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], 100.0)[0]
    _assert_rotation(out[:3, :3], atol=1e-15)
    step = rotation_log(out[:3, :3] @ T_ref[:3, :3].T)
    np.testing.assert_allclose(step, cf.lowpass_gain(100.0) * 1e-9 * axis, atol=1e-15)


def test_cartesian_lowpass_per_robot_cutoff_and_rows_are_independent():
    rng = np.random.default_rng(5)
    T_c = np.stack([_random_pose(rng) for _ in range(3)])
    T_ref = np.stack([_random_pose(rng) for _ in range(3)])
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
    axis = _unit(rng)
    R = _rot(axis, angle)
    q = rotation_to_quaternion(R[None])[0]
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(quaternion_to_rotation(q[None])[0], R, atol=1e-15)
    rotvec = rotation_log(R[None])[0]
    if angle < np.pi - 1e-6:
        np.testing.assert_allclose(rotvec, angle * axis, atol=1e-13)
    else:  # a half turn: axis and -axis are the same rotation
        assert min(np.abs(rotvec - angle * axis).max(), np.abs(rotvec + angle * axis).max()) < 1e-8
    np.testing.assert_allclose(rotation_exp(rotvec), R, atol=1e-14)


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


def _derivatives(x):
    v = x
    a = np.diff(v, axis=0) / DT
    return v, a, np.diff(a, axis=0) / DT


def test_velocity_step_from_rest_gives_one_jerk_limited_increment():
    rng = np.random.default_rng(0)
    u, w = _unit(rng), _unit(rng)
    target = np.concatenate([u, w])[None]  # 1 m/s and 1 rad/s
    zero = np.zeros((1, 6))
    out = cart.limit_rate_cartesian_velocity(target, zero, zero, *LIMITS)[0]
    np.testing.assert_allclose(out[:3], J * DT * DT * u, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(out[3:], J_ROT * DT * DT * w, rtol=1e-14, atol=1e-18)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), magnitude=st.floats(4.0, 50.0))
def test_velocity_limiter_ramp_to_an_unreachable_target_respects_v_a_j(seed, magnitude):
    rng = np.random.default_rng(seed)
    target = magnitude * np.concatenate([_unit(rng), _unit(rng)])[None]
    v, a, j = _derivatives(_run_velocity(lambda k: target, 1500)[:, 0])
    for half, (vm, am, jm) in ((slice(0, 3), (V, A, J)), (slice(3, 6), (V_ROT, A_ROT, J_ROT))):
        assert _norms(v[:, half]).max() <= vm * (1 + RTOL)
        assert _norms(a[:, half]).max() <= am * (1 + RTOL)
        assert _norms(j[:, half]).max() <= jm * (1 + RTOL)
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
    v, a, _ = _derivatives(_run_velocity(lambda k: commands[k], 600)[:, 0])
    for half, (vm, am) in ((slice(0, 3), (V, A)), (slice(3, 6), (V_ROT, A_ROT))):
        assert _norms(v[:, half]).max() <= vm * (1 + RTOL)
        assert _norms(a[:, half]).max() <= am * (1 + RTOL)


def test_velocity_limiter_converges_to_a_reachable_target_exactly():
    rng = np.random.default_rng(1)
    target = np.concatenate([0.5 * _unit(rng), 0.7 * _unit(rng)])[None]
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
    T = np.stack([_pose(t=(0.3, 0.0, 0.5))] + [_random_pose(rng) for _ in range(3)])
    zero = np.zeros((4, 6))
    with np.errstate(all="raise"):
        out = cart.limit_rate_cartesian_pose(T, T, zero, zero, *LIMITS)
    # Exactly for the identity orientation; otherwise R R^T is I only to rounding, and
    # that ~1e-16 rad "error" is a (tiny, allowed) command, as in libfranka.
    np.testing.assert_array_equal(out[0], T[0])
    np.testing.assert_allclose(out, T, rtol=0, atol=1e-15)


def test_pose_limiter_first_step_from_rest_is_jerk_limited_with_the_rotation_factor():
    rng = np.random.default_rng(1)
    T_last = _random_pose(rng)
    u, axis = _unit(rng), _unit(rng)
    T_c = _pose(_rot(axis, 0.1) @ T_last[:3, :3], T_last[:3, 3] + 0.01 * u)
    zero = np.zeros((1, 6))
    out = cart.limit_rate_cartesian_pose(T_c[None], T_last[None], zero, zero, *LIMITS)[0]
    np.testing.assert_allclose(out[:3, 3] - T_last[:3, 3], J * DT**3 * u, rtol=1e-9)
    step = rotation_log(out[:3, :3] @ T_last[:3, :3].T)
    np.testing.assert_allclose(step, POSE_FACTOR * J_ROT * DT**3 * axis, rtol=1e-9)
    np.testing.assert_array_equal(out[3], [0.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize("offset", [1e-3, 1e-9, 0.0])
def test_pose_limiter_differentiates_a_near_half_turn_about_the_right_axis(offset):
    rng = np.random.default_rng(2)
    T_last = _random_pose(rng)
    axis = _unit(rng)
    T_c = _pose(_rot(axis, np.pi - offset) @ T_last[:3, :3], T_last[:3, 3])
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
    T0 = _random_pose(rng)
    axis, direction = _unit(rng), _unit(rng)
    T_target = _pose(_rot(axis, 2.5) @ T0[:3, :3], T0[:3, 3] + 2.0 * direction)
    poses = _run_pose(T0[None], T_target[None], 1500)[:, 0]
    _assert_rotation(poses[:, :3, :3], atol=1e-12)
    np.testing.assert_array_equal(poses[:, 3], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (1501, 4)))
    twists = _twist_between(poses[:-1], poses[1:])
    v, a, j = _derivatives(twists)
    rot = (POSE_FACTOR * V_ROT, POSE_FACTOR * A_ROT, POSE_FACTOR * J_ROT)
    for half, (vm, am, jm) in ((slice(0, 3), (V, A, J)), (slice(3, 6), rot)):
        speed = _norms(v[:, half])
        assert speed.max() <= vm * (1 + RTOL)
        assert speed.max() >= vm * (1 - RTOL)  # the limit, scaled by 0.99 for rotation, is hit
        assert _norms(a[:, half]).max() <= am * (1 + RTOL)
        assert _norms(j[:, half]).max() <= jm * (1 + RTOL)
    # On the way there (both still short of the target after 700 cycles) the motion
    # stays on the straight line / about the fixed axis. Later, oscillating about the
    # target (see the overshoot test), rounding off the line grows slowly -- as with
    # libfranka itself -- so the check stops here.
    approach = poses[:700]
    travelled = approach[:, :3, 3] - T0[:3, 3]
    assert (travelled @ direction).max() < 2.0
    np.testing.assert_allclose(np.cross(travelled, direction), 0.0, atol=1e-10)
    turned = rotation_log(approach[:, :3, :3] @ T0[:3, :3].T)
    assert _norms(turned).max() < 2.5
    np.testing.assert_allclose(np.cross(turned, axis), 0.0, atol=1e-10)


def test_pose_limiter_is_no_trajectory_planner_a_step_target_overshoots():
    # The twist toward the target is (target - last) / dt: nothing plans the braking, so
    # at full speed the limiter runs past the target (as libfranka does; motion
    # generators must be smooth themselves).
    T0 = _pose()
    T_target = _pose(t=(1.0, 0.0, 0.0))
    x = _run_pose(T0[None], T_target[None], 1200)[:, 0, 0, 3]
    assert x.max() > 1.05


def test_pose_limiter_rows_are_independent_of_the_batch():
    rng = np.random.default_rng(3)
    T_last = np.stack([_random_pose(rng) for _ in range(3)])
    T_c = np.stack(
        [
            _pose(rotation_exp(0.01 * rng.normal(size=3)) @ T[:3, :3], T[:3, 3] + 0.002)
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
    _assert_rotation(out[:, :3, :3])


def test_pose_limiter_rejects_non_finite_then_invalid_transforms():
    T = np.eye(4)[None]
    zero = np.zeros((1, 6))
    nan = T.copy()
    nan[0, 0, 0] = np.nan  # also not a valid rotation: the finite check comes first
    with pytest.raises(ValueError, match="O_T_EE_c is infinite or NaN."):
        cart.limit_rate_cartesian_pose(nan, T, zero, zero, *LIMITS)
    for broken in (np.diag([1.0, 1.0, 1.1, 1.0]), _pose(t=(1, 2, 3)).T):  # scaled / transposed
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


def _pose_rv(rotvec, t):
    return _pose(rotation_exp(np.array(rotvec, dtype=float)), t)


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


#: (T_c, T_last, twist, dtwist, expected): libfranka's limitRate on poses (also the C
#: kernel's test, tests/envs/test_native_client.py).
LIBFRANKA_POSE_LIMITER_CASES = [
    (
        _pose_rv([0.3, -0.2, 0.1], [0.4, 0.1, 0.5]),
        _pose_rv([0.31, -0.19, 0.12], [0.401, 0.099, 0.5005]),
        [0.5, -0.2, 0.1, 0.3, 0.2, -0.4],
        [3.0, 1.0, -2.0, 5.0, -4.0, 1.0],
        [[0.9751320474685167, -0.14574068037303958, -0.16696449947297792, 0.40149964093766416],
         [0.087539453573915, 0.9453929385007624, -0.3139570606004492, 0.09880367965119143],
         [0.2036033744018967, 0.2915336102704066, 0.9346410113058723, 0.5005966635267619],
         [0.0, 0.0, 0.0, 1.0]],
    ),
    (  # a 2.9 rad difference: the quaternion's largest-diagonal branch
        _pose_rv([2.0, -1.0, 0.5], [0.0, 0.0, 0.0]),
        _pose_rv([-2.0, 1.5, 0.1], [0.1, 0.0, 0.0]),
        [0.0] * 6,
        [0.0] * 6,
        [[0.3493156539013705, -0.8875968976556621, 0.30025043082650543, 0.099995500001],
         [-0.8398877155992565, -0.15453769058843903, 0.5202948465755299, 0.0],
         [-0.41541208350855696, -0.43392378300761075, -0.7994641651853092, 0.0],
         [0.0, 0.0, 0.0, 1.0]],
    ),
]  # fmt: skip


@pytest.mark.parametrize(
    ("T_c", "T_last", "twist", "dtwist", "expected"), LIBFRANKA_POSE_LIMITER_CASES
)
def test_pose_limiter_matches_libfranka(T_c, T_last, twist, dtwist, expected):
    out = cart.limit_rate_cartesian_pose(
        T_c[None], T_last[None], np.array([twist]), np.array([dtwist]), *LIMITS
    )
    np.testing.assert_allclose(out[0], expected, rtol=0, atol=1e-14)


#: (T_c, T_ref, cutoff, expected): libfranka's cartesianLowpassFilter (also the C
#: kernel's test).
LIBFRANKA_LOWPASS_CASES = [
    (
        _pose_rv([0.3, -0.2, 0.1], [1, 2, 3]),
        _pose_rv([0.2, 0.1, -0.3], [0, 0, 1]),
        100.0,
        [[0.9892603520923969, 0.14233830515481044, -0.03322292376782669, 0.3858695450950375],
         [-0.1461552922368075, 0.9608073166901957, -0.23555876282948898, 0.771739090190075],
         [-0.0016082068275449397, 0.2378846507873976, 0.9712920809882873, 1.771739090190075],
         [0.0, 0.0, 0.0, 1.0]],
    ),
    (  # the quaternion sign flip
        _pose_rv([0.0, 0.0, np.radians(-100.0)], [0, 0, 0]),
        _pose_rv([0.0, 0.0, np.radians(100.0)], [0, 0, 0]),
        30.0,
        [[-0.5789399948819778, -0.8153701504997939, 0.0, 0.0],
         [0.8153701504997939, -0.5789399948819778, 0.0, 0.0],
         [0.0, 0.0, 1.0, 0.0],
         [0.0, 0.0, 0.0, 1.0]],
    ),
    (  # both near a half turn: negative traces
        _pose_rv([2.9, 0.3, -0.2], [0.5, 0.5, 0.5]),
        _pose_rv([-0.4, 2.8, 0.9], [0.4, 0.6, 0.5]),
        10.0,
        [[-0.8899231892450603, -0.45608685308377445, 0.004636775608154287, 0.40591173974417494],
         [-0.3631180334367878, 0.7145996777932448, 0.5979068441578426, 0.5940882602558251],
         [-0.27601088934478774, 0.5304074687840759, -0.8015521854634102, 0.5],
         [0.0, 0.0, 0.0, 1.0]],
    ),
]  # fmt: skip


@pytest.mark.parametrize(("T_c", "T_ref", "cutoff", "expected"), LIBFRANKA_LOWPASS_CASES)
def test_cartesian_lowpass_matches_libfranka(T_c, T_ref, cutoff, expected):
    out = cart.cartesian_lowpass_filter(T_c[None], T_ref[None], cutoff)
    np.testing.assert_allclose(out[0], expected, rtol=0, atol=1e-14)
