"""libfranka's client-side low-pass filter and rate limiter (docs/limits.md §6), batch-first."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.envs import client_filters as cf
from franka_sim_gym.fci.tables import FR3

DT = 1e-3
HOME = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
A = FR3.ddq_max  # kMaxJointAcceleration = 9.999
J = FR3.dddq_max  # kMaxJointJerk = 4999.999
#: What the robot checks (docs/limits.md §5): the limits themselves, 1e-3 above libfranka's targets.
ROBOT_DDQ = 10.0
ROBOT_DDDQ = 5000.0


def _scalar_limit_rate(upper, lower, a_max, j_max, v_c, v_last, a_last):
    """src/rate_limiting.cpp, scalar velocity overload, transcribed line by line."""
    jerk = (((v_c - v_last) / DT) - a_last) / DT
    acc = a_last + max(min(jerk, j_max), -j_max) * DT
    safe_max = min((j_max / a_max) * (upper - v_last), a_max)
    safe_min = max((j_max / a_max) * (lower - v_last), -a_max)
    return v_last + max(min(acc, safe_max), safe_min) * DT


def _diffs(x):
    """Backward differences, as the robot forms them from consecutive commands."""
    v = np.diff(x, axis=0) / DT
    a = np.diff(v, axis=0) / DT
    return v, a, np.diff(a, axis=0) / DT


# --- low-pass filter ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cutoff", "gain"),
    [(10.0, 0.059117), (30.0, 0.158600), (50.0, 0.239057), (100.0, 0.385870), (500.0, 0.758547)],
)
def test_lowpass_gain_matches_limits_md_table_to_6_digits(cutoff, gain):
    assert cf.lowpass_gain(cutoff) == pytest.approx(gain, abs=5e-7)


def test_lowpass_constants_are_libfrankas():
    assert cf.LOWPASS_DEFAULT_CUTOFF == 100.0
    assert cf.MAX_CUTOFF_FREQUENCY == 1000.0
    assert cf.lowpass_gain(100.0, dt=2e-3) == pytest.approx(2e-3 / (2e-3 + 1 / (200 * math.pi)))


def test_lowpass_filter_is_gain_weighted_mean_of_command_and_reference():
    rng = np.random.default_rng(0)
    x, ref = rng.normal(size=(3, 7)), rng.normal(size=(3, 7))
    g = cf.lowpass_gain(100.0)
    np.testing.assert_allclose(cf.lowpass_filter(x, ref, 100.0), g * x + (1 - g) * ref, atol=0)
    # A settled signal stays put -- to 1 ulp, as in libfranka: g*x + (1-g)*x is not x exactly.
    np.testing.assert_array_max_ulp(cf.lowpass_filter(x, x, 30.0), x, maxulp=1)


def test_lowpass_filter_at_max_cutoff_still_filters_disabling_is_the_callers_job():
    # ControlLoop skips lowpassFilter when cutoff >= kMaxCutoffFrequency; the function
    # itself has no such switch: at 1000 Hz its gain is 0.8627, not 1.
    x, ref = np.ones((1, 7)), np.zeros((1, 7))
    out = cf.lowpass_filter(x, ref, cf.MAX_CUTOFF_FREQUENCY)
    np.testing.assert_allclose(out, 0.8626974, atol=1e-7)


def test_lowpass_filter_per_robot_cutoff_broadcasts():
    x, ref = np.ones((2, 7)), np.zeros((2, 7))
    out = cf.lowpass_filter(x, ref, np.array([[10.0], [100.0]]))
    np.testing.assert_allclose(out[0], cf.lowpass_gain(10.0))
    np.testing.assert_allclose(out[1], cf.lowpass_gain(100.0))


@pytest.mark.parametrize("cutoff", [0.0, -5.0, math.nan, math.inf])
def test_lowpass_rejects_cutoff_not_positive_finite(cutoff):
    with pytest.raises(ValueError, match="cutoff_frequency is zero, negative, infinite or NaN"):
        cf.lowpass_filter(np.zeros((1, 7)), np.zeros((1, 7)), cutoff)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_lowpass_rejects_non_finite_signal_naming_the_argument(bad):
    x = np.zeros((2, 7))
    x[1, 3] = bad
    with pytest.raises(ValueError, match=r"^x: lowpass-filter: .* infinite or NaN"):
        cf.lowpass_filter(x, np.zeros((2, 7)))
    with pytest.raises(ValueError, match=r"^x_ref: "):
        cf.lowpass_filter(np.zeros((2, 7)), x)


def test_lowpass_first_position_cycle_reference_is_command_so_identity():
    # ControlLoop<JointPositions>::convertMotion: first cycle, reference = the command.
    # Identity to 1 ulp: libfranka evaluates g*x + (1-g)*x, which may round.
    q_c = HOME[None] + 0.2
    np.testing.assert_array_max_ulp(cf.lowpass_filter(q_c, q_c), q_c, maxulp=1)


# --- joint rate limiter: libfranka's arithmetic -------------------------------------------


def test_velocity_limiter_equals_scalar_libfranka_transcription_bit_for_bit():
    rng = np.random.default_rng(1)
    n = 64
    v_last = rng.uniform(-3, 3, (n, 7))
    a_last = rng.uniform(-12, 12, (n, 7))
    v_c = v_last + rng.normal(scale=rng.choice([1e-4, 1e-2, 1.0], (n, 7)))
    upper, lower = FR3.velocity_envelope(rng.uniform(FR3.q_lower, FR3.q_upper, (n, 7)))
    out = cf.limit_rate_joint_velocities(v_c, v_last, a_last, upper, lower, A, J)
    for i in range(n):
        for k in range(7):
            ref = _scalar_limit_rate(
                upper[i, k], lower[i, k], A[k], J[k], v_c[i, k], v_last[i, k], a_last[i, k]
            )
            assert out[i, k] == ref


def test_velocity_limiter_lower_bound_wins_when_band_is_empty():
    # v_last far below `lower`: safe_min = J/A (lower - v_last) > A = safe_max;
    # libfranka's max(min(a, hi), lo) returns lo (np.clip would return hi).
    v_last = np.full((1, 7), -3.0)
    upper, lower = np.full((1, 7), 2.0), np.full((1, 7), -1.0)
    out = cf.limit_rate_joint_velocities(v_last, v_last, np.zeros((1, 7)), upper, lower, A, J)
    lo = (J / A) * (lower - v_last)
    np.testing.assert_array_equal(out, v_last + lo * DT)


def test_position_limiter_differentiates_limits_and_reintegrates():
    rng = np.random.default_rng(2)
    q_last = HOME + rng.uniform(-0.3, 0.3, (5, 7))
    dq, ddq = rng.uniform(-1, 1, (5, 7)), rng.uniform(-5, 5, (5, 7))
    q_c = q_last + rng.uniform(-0.01, 0.01, (5, 7))
    upper, lower = FR3.velocity_envelope(q_last)
    v = cf.limit_rate_joint_velocities((q_c - q_last) / DT, dq, ddq, upper, lower, A, J)
    out = cf.limit_rate_joint_positions(q_c, q_last, dq, ddq, upper, lower, A, J)
    np.testing.assert_array_equal(out, q_last + v * DT)


def test_position_limiter_first_cycle_at_rest_is_identity():
    # First cycle: reference (and last position) = the command, dq_d = ddq_d = 0.
    q_c = HOME[None] + 0.2
    zeros = np.zeros((1, 7))
    upper, lower = FR3.velocity_envelope(q_c)
    np.testing.assert_array_equal(
        cf.limit_rate_joint_positions(q_c, q_c, zeros, zeros, upper, lower, A, J), q_c
    )


# --- joint rate limiter: what it guarantees ------------------------------------------------


def _conforming(amp, omega, steps):
    """q(t) = amp (1 - cos(omega t))^2: starts at rest with zero acceleration, smooth."""
    t = np.arange(steps)[:, None] * DT
    return amp * (1.0 - np.cos(omega * t)) ** 2


@settings(max_examples=10, deadline=None)
@given(amp=st.floats(-0.1, 0.1), omega=st.floats(0.5, 3.0))
def test_conforming_position_command_passes_unchanged(amp, omega):
    # Up to 0.4 rad from home: inside every joint's range, well inside its envelope.
    q = HOME + _conforming(amp, omega, 400)
    v, a, j = _diffs(q)
    assert np.abs(v).max() < 2.0 and np.abs(a).max() < 9.0 and np.abs(j).max() < 4000.0
    q_d, dq_d, ddq_d = q[2][None], v[1][None], a[0][None]
    for k in range(3, len(q)):
        upper, lower = FR3.velocity_envelope(q_d)
        out = cf.limit_rate_joint_positions(q[k][None], q_d, dq_d, ddq_d, upper, lower, A, J)
        np.testing.assert_allclose(out[0], q[k], rtol=0, atol=1e-12)
        v_new = (out - q_d) / DT
        q_d, dq_d, ddq_d = out, v_new, (v_new - dq_d) / DT


@settings(max_examples=10, deadline=None)
@given(amp=st.floats(-0.1, 0.1), omega=st.floats(0.5, 6.0))
def test_conforming_velocity_command_passes_unchanged(amp, omega):
    dq = _conforming(amp, omega, 400) * np.linspace(1, 3, 7)
    a, j = np.diff(dq, axis=0) / DT, np.diff(dq, n=2, axis=0) / DT**2
    assert np.abs(dq).max() < 2.0 and np.abs(a).max() < 9.0 and np.abs(j).max() < 4000.0
    dq_d, ddq_d = dq[1][None], a[0][None]
    upper, lower = FR3.velocity_envelope(HOME[None])
    for k in range(2, len(dq)):
        out = cf.limit_rate_joint_velocities(dq[k][None], dq_d, ddq_d, upper, lower, A, J)
        np.testing.assert_allclose(out[0], dq[k], rtol=0, atol=1e-12)
        dq_d, ddq_d = out, (out - dq_d) / DT


def _random_stream(rng, steps, n):
    """Held random targets with noise and occasional huge jumps: a hostile command stream."""
    switch = rng.random(steps) < 1 / 30
    level = rng.uniform(-6, 6, (steps, n, 7))
    out = np.empty((steps, n, 7))
    current = level[0]
    for k in range(steps):
        if switch[k]:
            current = level[k]
        out[k] = current + rng.normal(scale=0.05, size=(n, 7))
    return out


@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    a_max=st.floats(2.0, 20.0),
    c=st.floats(0.05, 1.0),  # J dt / A <= 1: the limiter's design condition (FR3: 0.50005)
)
def test_velocity_limiter_stream_respects_velocity_acceleration_jerk_bounds(seed, a_max, c):
    rng = np.random.default_rng(seed)
    n, steps = 4, 400
    j_max = c * a_max / DT
    upper = rng.uniform(0.1, 3.0, (n, 7))
    lower = -rng.uniform(0.1, 3.0, (n, 7))
    commands = _random_stream(rng, steps, n)
    dq_d, ddq_d = np.zeros((n, 7)), np.zeros((n, 7))
    stream = [dq_d]
    for k in range(steps):
        out = cf.limit_rate_joint_velocities(commands[k], dq_d, ddq_d, upper, lower, a_max, j_max)
        dq_d, ddq_d = out, (out - dq_d) / DT
        stream.append(out)
    dq = np.array(stream)
    acc = np.diff(dq, axis=0) / DT
    jerk = np.diff(acc, axis=0) / DT
    assert (dq <= upper + 1e-12).all() and (dq >= lower - 1e-12).all()
    assert np.abs(acc).max() <= a_max * (1 + 1e-9)
    assert np.abs(jerk).max() <= j_max * (1 + 1e-9) + 1e-6
    assert np.abs(jerk[0]).max() <= j_max * (1 + 1e-9)  # from rest: the first step too


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_position_limiter_stream_respects_fr3_acceleration_jerk_and_velocity_bounds(seed):
    # Constant velocity bounds (the FR3 nameplate minus tol), libfranka's FR3 A and J; the
    # robot's checks on backward differences of the sent positions must hold.
    rng = np.random.default_rng(seed)
    n, steps = 3, 400
    upper = np.broadcast_to(FR3.dq_max - 1e-3, (n, 7))
    commands = HOME + _random_stream(rng, steps, n) * 0.2
    q_d, dq_d, ddq_d = np.broadcast_to(HOME, (n, 7)), np.zeros((n, 7)), np.zeros((n, 7))
    stream = [q_d]
    for k in range(steps):
        out = cf.limit_rate_joint_positions(commands[k], q_d, dq_d, ddq_d, upper, -upper, A, J)
        v = (out - q_d) / DT
        q_d, dq_d, ddq_d = out, v, (v - dq_d) / DT
        stream.append(out)
    v, a, j = _diffs(np.array(stream))
    assert (np.abs(v) <= upper + 1e-9).all()
    assert np.abs(a).max() <= A.max() + 1e-6
    assert np.abs(j).max() <= J.max() + 1e-3  # differencing noise of O(1e-6) at most
    assert np.abs(a).max() < ROBOT_DDQ and np.abs(j).max() < ROBOT_DDDQ


@pytest.mark.parametrize("with_lowpass", [False, True])
def test_one_rad_step_becomes_jerk_limited_ramp_the_robot_accepts(with_lowpass):
    # Robot::control(limit_rate=true) on a +1 rad step of every joint from home: the
    # limiter turns it into a ramp whose backward differences stay inside the robot's
    # limits (10 rad/s^2, 5000 rad/s^3, the position-based envelope at the last command).
    target = HOME[None] + 1.0
    q_d, dq_d, ddq_d = HOME[None].copy(), np.zeros((1, 7)), np.zeros((1, 7))
    stream = [q_d]
    for _ in range(900):
        cmd = cf.lowpass_filter(target, q_d) if with_lowpass else target
        upper, lower = FR3.velocity_envelope(q_d)
        out = cf.limit_rate_joint_positions(cmd, q_d, dq_d, ddq_d, upper, lower, A, J)
        v = (out - q_d) / DT
        q_d, dq_d, ddq_d = out, v, (v - dq_d) / DT
        stream.append(out)
    q = np.array(stream)[:, 0]
    v, a, j = _diffs(q)
    # The first cycle moves by one jerk step only: J dt^3.
    np.testing.assert_allclose(q[1] - HOME, J * DT**3, rtol=1e-9)
    assert np.abs(a).max() <= A.max() + 1e-9 and np.abs(a).max() < ROBOT_DDQ
    assert np.abs(j).max() <= J.max() + 1e-3 and np.abs(j).max() < ROBOT_DDDQ
    envelope = np.array([FR3.velocity_envelope(qk) for qk in q[:-1]])
    robot_tol = 1e-3  # the envelope already subtracts libfranka's tolerance
    assert (v <= envelope[:, 0] + robot_tol).all() and (v >= envelope[:, 1] - robot_tol).all()
    # A ramp, not a jump: monotone up to the target, which every joint reaches.
    first_arrival = np.argmax(q >= target, axis=0)
    assert (first_arrival > 300).all()  # >= 1 rad at <= 2.62 rad/s takes >= 0.38 s
    for k in range(7):
        assert (np.diff(q[: first_arrival[k] + 1, k]) > 0).all()


def test_joint_limiters_batch_rows_are_independent():
    rng = np.random.default_rng(3)
    n = 6
    q_last = HOME + rng.uniform(-0.5, 0.5, (n, 7))
    dq, ddq = rng.uniform(-2, 2, (n, 7)), rng.uniform(-9, 9, (n, 7))
    q_c = q_last + rng.normal(scale=[[1e-4], [1e-2], [1.0], [1e-3], [0.1], [1e-5]], size=(n, 7))
    upper, lower = FR3.velocity_envelope(q_last)
    batch_q = cf.limit_rate_joint_positions(q_c, q_last, dq, ddq, upper, lower, A, J)
    batch_v = cf.limit_rate_joint_velocities(q_c - q_last, dq, ddq, upper, lower, A, J)
    for i in range(n):
        row = slice(i, i + 1)
        one_q = cf.limit_rate_joint_positions(
            q_c[row], q_last[row], dq[row], ddq[row], upper[row], lower[row], A, J
        )
        one_v = cf.limit_rate_joint_velocities(
            q_c[row] - q_last[row], dq[row], ddq[row], upper[row], lower[row], A, J
        )
        np.testing.assert_array_equal(batch_q[row], one_q)
        np.testing.assert_array_equal(batch_v[row], one_v)


# --- torque rate limiter ------------------------------------------------------------------


def test_torque_rate_is_clamped_and_reintegrated():
    tau_last = np.array([[0.0] * 7, [5.0] * 7])
    tau_c = np.array([[10.0, -10.0, 5e-4, -5e-4, 0.0, 1.0, -1.0], [5.0] * 7])
    out = cf.limit_rate_torques(tau_c, tau_last, FR3.dtau_max)
    step = FR3.dtau_max * DT  # 0.999999 Nm per cycle
    np.testing.assert_allclose(
        out[0], [step, -step, 5e-4, -5e-4, 0.0, step, -step], rtol=0, atol=1e-15
    )
    np.testing.assert_array_equal(out[1], tau_last[1])
    assert (np.abs(np.diff(np.stack([tau_last, out]), axis=0)) / DT <= FR3.dtau_max + 1e-9).all()


def test_torque_rate_limiter_rows_are_independent():
    rng = np.random.default_rng(4)
    tau_c, tau_last = rng.normal(scale=3, size=(4, 7)), rng.normal(scale=3, size=(4, 7))
    out = cf.limit_rate_torques(tau_c, tau_last, FR3.dtau_max)
    for i in range(4):
        np.testing.assert_array_equal(
            out[i : i + 1], cf.limit_rate_torques(tau_c[i : i + 1], tau_last[i : i + 1], 999.999)
        )


# --- non-finite inputs --------------------------------------------------------------------


def _with_nan(shape=(2, 7)):
    x = np.zeros(shape)
    x[-1, -1] = math.nan
    return x


def test_non_finite_commands_raise_libfrankas_message():
    z, up = np.zeros((2, 7)), np.ones((2, 7))
    msg = r"Commanding value is infinite or NaN\. \(libfranka throws std::invalid_argument\)"
    with pytest.raises(ValueError, match=r"^q_c: " + msg):
        cf.limit_rate_joint_positions(_with_nan(), z, z, z, up, -up, A, J)
    with pytest.raises(ValueError, match=r"^dq_c: " + msg):
        cf.limit_rate_joint_velocities(_with_nan(), z, z, up, -up, A, J)
    with pytest.raises(ValueError, match=r"^tau_c: " + msg):
        cf.limit_rate_torques(np.full((2, 7), math.inf), z, 999.999)


@pytest.mark.parametrize("position", range(1, 8))
def test_non_finite_references_and_limits_raise_naming_the_argument(position):
    z, up = np.zeros((2, 7)), np.ones((2, 7))
    args = [z, z, z, z, up, -up, A, J]
    names = ["q_c", "q_last", "dq_last", "ddq_last", "upper", "lower", "ddq_max", "dddq_max"]
    args[position] = _with_nan(np.shape(args[position]) if position < 6 else (1, 7))
    with pytest.raises(ValueError, match=rf"^{names[position]} contains NaN or infinite entries"):
        cf.limit_rate_joint_positions(*args)


def test_non_finite_velocity_and_torque_references_raise_naming_the_argument():
    z, up = np.zeros((2, 7)), np.ones((2, 7))
    with pytest.raises(ValueError, match=r"^dq_last contains NaN"):
        cf.limit_rate_joint_velocities(z, _with_nan(), z, up, -up, A, J)
    with pytest.raises(ValueError, match=r"^tau_last contains NaN"):
        cf.limit_rate_torques(z, _with_nan(), 999.999)
