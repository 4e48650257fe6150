"""The env client's libfranka filters in C (envs/_client_filters.c) against their numpy
references, bit for bit: the low-pass filter with the joint rate limiter, and with the
twist rate limiter.

Joint states sweep the ranges and head into the stops with the band binding; twist
states sweep the corners of the norm limiter: at rest (no jerk, no acceleration),
inside the velocity ball, at its surface and outside it (the square root's negative
argument), and jerks far past the limit, on both halves of the twist. End to end,
random-action episodes are the same bit for bit with and without the kernels.
"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym import native
from franka_sim_gym.envs import client_filters as cf
from franka_sim_gym.envs.commands import CommandGenerator
from franka_sim_gym.fci.frames import from_wire, is_homogeneous, to_wire
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE
from franka_sim_gym.sim.kinematics import rotation_exp
from tests.envs.test_client_filters_cartesian import LIBFRANKA_LOWPASS_CASES as LOWPASS_CASES
from tests.envs.test_client_filters_cartesian import (
    LIBFRANKA_POSE_LIMITER_CASES as POSE_LIMITER_CASES,
)
from tests.envs.test_client_filters_cartesian import LIMITS as LIBFRANKA_LIMITS
from tests.native_helpers import joint_and_client_kernels_off, joint_samples, rollout, same_bits

kernel = native.load("envs._client_filters")
pytestmark = pytest.mark.skipif(kernel is None, reason="envs/_client_filters.c not built")


def _random_state(rng, n: int, near_band: bool) -> np.ndarray:
    """A wire state (float32 fields, packed records) with q_d, dq_d, ddq_d: anywhere, or
    heading into a stop with the band binding."""
    s = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
    q = joint_samples(rng, n)
    dq = rng.normal(0, 1.0, (n, 7))
    if near_band:
        q = FR3.q_upper - rng.random((n, 7)) * 0.05
        dq = rng.random((n, 7)) * 1.0
    s["q_d"] = q
    s["dq_d"] = dq
    s["ddq_d"] = rng.normal(0, 6.0, (n, 7))
    s["tau_J_d"] = rng.normal(0, 5.0, (n, 7))
    return s


@pytest.mark.parametrize("interface", ["joint_position", "joint_velocity"])
@pytest.mark.parametrize("n", [1, 16])
def test_rate_limiter_kernel_is_libfrankas_filter_bit_for_bit(interface, n):
    gen = CommandGenerator(interface, "limit_rate", 40, n=n)
    assert gen._kernel is not None
    rng = np.random.default_rng(11 + n)
    for trial in range(300):
        state = _random_state(rng, n, near_band=trial % 3 == 0)
        gen.reset()
        gen.begin_step(rng.uniform(-1, 1, (n, 7)), state)
        if trial % 2:
            gen._first[: n // 2 + 1] = False  # a mix of first commands and filtered ones
            gen._n_first = int(np.count_nonzero(gen._first))
        else:
            gen._first[...] = False
            gen._n_first = 0
        fast = gen._filtered(state).copy()
        kernel_fn, gen._kernel = gen._kernel, None
        reference = gen._filtered(state)
        gen._kernel = kernel_fn
        assert same_bits(fast, reference), (trial, np.max(np.abs(fast - reference)))


@pytest.mark.parametrize("n", [1, 16])
def test_torque_limiter_kernel_is_libfrankas_filter_bit_for_bit(n):
    """Torque commands within the rate bound, far past it either way, and at rest."""
    gen = CommandGenerator("torque", "limit_rate", 40, n=n)
    assert gen._torque_kernel is not None
    rng = np.random.default_rng(21 + n)
    for trial in range(300):
        state = _random_state(rng, n, near_band=False)
        state["tau_J_d"] = rng.normal(0, 20.0, (n, 7)) * (trial % 4 != 0)
        gen.begin_step(rng.uniform(-1, 1, (n, 7)) * (trial % 5 != 0), state)
        fast = gen._filtered(state).copy()
        kernel_fn, gen._torque_kernel = gen._torque_kernel, None
        reference = gen._filtered(state)
        gen._torque_kernel = kernel_fn
        assert same_bits(fast, reference), (trial, np.max(np.abs(fast - reference)))
        if trial % 4 == 0:  # from rest, a full action asks ~20 Nm at once: rate-limited
            steps = np.abs(fast - state["tau_J_d"]) / gen._dtau_max / 1e-3
            assert np.all(steps <= 1.0 + 1e-9)


def test_a_non_finite_torque_takes_the_reference_path():
    gen = CommandGenerator("torque", "limit_rate", 40)
    state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
    gen.begin_step(np.zeros((1, 7)), state)
    target = gen._target.copy()
    target[0, 3] = np.nan
    out = np.full((1, 7), 7.0)
    assert kernel.limit_torques(target, state["tau_J_d"], gen._gain, 998.0, out) is False
    assert np.all(out == 7.0)  # untouched
    # The generator then answers with numpy's path: the NaN on joint 3 alone, as numpy's
    # minimum and maximum propagate it, the other joints filtered as ever.
    gen._target = target
    answered = gen._filtered(state)
    assert answered is not gen._out
    kernel_fn, gen._torque_kernel = gen._torque_kernel, None
    reference = gen._filtered(state)
    gen._torque_kernel = kernel_fn
    assert np.isnan(answered[0, 3]) and np.isfinite(np.delete(answered[0], 3)).all()
    assert np.array_equal(answered, reference, equal_nan=True)
    with pytest.raises(TypeError, match=r"limit_torques\(\) takes 5 arguments"):
        kernel.limit_torques(target, state["tau_J_d"], gen._gain, 998.0)


def _twist_state(rng, n: int, regime: str) -> np.ndarray:
    s = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
    if regime == "rest":
        return s
    direction = rng.normal(size=(n, 6))
    speed = {"inside": 0.5, "surface": 1.0, "outside": 1.3}[regime]
    # Around the default ("conservative") limits' balls (0.5 m/s, 1.0 rad/s), per half.
    twist = direction.reshape(n, 2, 3)
    twist /= np.linalg.norm(twist, axis=-1, keepdims=True)
    twist *= speed * np.array([0.5, 1.0])[None, :, None]
    s["O_dP_EE_c"] = twist.reshape(n, 6)
    s["O_ddP_EE_c"] = rng.normal(0, 1.0, (n, 6))
    return s


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("regime", ["rest", "inside", "surface", "outside"])
def test_twist_limiter_kernel_is_libfrankas_filter_bit_for_bit(n, regime):
    gen = CommandGenerator("cartesian_velocity", "limit_rate", 40, n=n)
    assert gen._twist_kernel is not None
    rng = np.random.default_rng(n + len(regime))
    for trial in range(200):
        state = _twist_state(rng, n, regime)
        action = rng.uniform(-1, 1, (n, 6)) * (0.0 if trial % 5 == 0 else 1.0)
        gen.begin_step(action, state)
        fast = gen._filtered(state).copy()
        kernel_fn, gen._twist_kernel = gen._twist_kernel, None
        reference = gen._filtered(state)
        gen._twist_kernel = kernel_fn
        assert same_bits(fast, reference), (trial, np.max(np.abs(fast - reference)))


def test_an_acceleration_that_rounds_to_nothing_leaves_the_twist_as_it_was():
    """At rest with a last acceleration of ~1e-13: the jerk takes it back to |a| <= eps,
    where libfranka returns v_last itself (its kNormEps branch)."""
    gen = CommandGenerator("cartesian_velocity", "limit_rate", 40, n=16)
    rng = np.random.default_rng(2)
    for _ in range(50):
        state = np.zeros(16, dtype=ROBOT_STATE_DTYPE)
        state["O_ddP_EE_c"] = rng.normal(0, 1e-13, (16, 6))
        gen.begin_step(np.zeros((16, 6)), state)
        fast = gen._filtered(state).copy()
        kernel_fn, gen._twist_kernel = gen._twist_kernel, None
        reference = gen._filtered(state)
        gen._twist_kernel = kernel_fn
        assert same_bits(fast, reference)


def test_a_non_finite_input_takes_the_reference_path_and_its_error():
    gen = CommandGenerator("cartesian_velocity", "limit_rate", 40)
    state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
    gen.begin_step(np.zeros((1, 6)), state)
    state["O_ddP_EE_c"][0, 4] = np.nan
    out = np.full((1, 6), 7.0)
    assert (
        kernel.limit_twist(
            gen._target, state["O_dP_EE_c"], state["O_ddP_EE_c"], 1.0, gen._twist_limits, out
        )
        is False
    )
    assert np.all(out == 7.0)  # untouched
    with pytest.raises(ValueError, match="dtwist_last"):
        gen._filtered(state)


def test_the_kernel_names_a_bad_argument():
    limits = np.ones(6)
    with pytest.raises(ValueError, match="ref: axis 0 has length 1, expected 2"):
        kernel.limit_twist(
            np.zeros((2, 6)), np.zeros((1, 6)), np.zeros((2, 6)), 1.0, limits, np.zeros((2, 6))
        )
    with pytest.raises(ValueError, match="limits"):
        kernel.limit_twist(
            np.zeros((2, 6)), np.zeros((2, 6)), np.zeros((2, 6)), 1.0, limits[:5], np.zeros((2, 6))
        )


@pytest.mark.parametrize(
    "interface", ["joint_position", "joint_velocity", "cartesian_velocity", "torque"]
)
def test_an_episode_is_the_same_with_and_without_the_kernels(interface, monkeypatch):
    """End to end, random actions through libfranka's limiters (reflexes included): the
    joint rules' and the client's kernels change no bit of what a policy sees."""
    fast = rollout(interface, "limit_rate")
    joint_and_client_kernels_off(monkeypatch)
    reference = rollout(interface, "limit_rate")
    assert len(fast) == len(reference)
    for a, b in zip(fast, reference, strict=True):
        assert same_bits(a, b)


# -- the Cartesian pose path: to rounding (libm's trigonometry, an iterated polar factor) ----

#: How far the pose kernel may be from its numpy reference and from libfranka: rounding
#: (its acos, atan2, sin, cos are libm's, as Eigen's are; numpy's SIMD ones may differ by
#: an ulp; its 3x3 products sum in another order than BLAS's).
POSE_ATOL = 1e-13


def _pose_state(rng, n: int, regime: str) -> np.ndarray:
    """A wire state at poses of every orientation (all four branches of Shepperd's method),
    with the last twist and its rate in a regime of the norm limiter."""
    s = _twist_state(rng, n, regime)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = rotation_exp(rng.normal(size=(n, 3)) * rng.uniform(0.0, 3.1, (n, 1)))
    T[:, :3, 3] = rng.normal(0, 0.4, (n, 3))
    s["O_T_EE_c"] = to_wire(T)
    return s


def _moved(rng, state: np.ndarray, step: float) -> np.ndarray:
    """The state with O_T_EE_c moved by up to ``step`` (m, rad): the motion under way."""
    s = state.copy()
    n = len(s)
    T = from_wire(s["O_T_EE_c"])
    T[:, :3, 3] += rng.normal(0, step, (n, 3))
    T[:, :3, :3] = rotation_exp(rng.normal(0, step, (n, 3))) @ T[:, :3, :3]
    s["O_T_EE_c"] = to_wire(T)
    return s


@pytest.mark.parametrize("action_filter", ["lowpass", "limit_rate"])
@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("regime", ["rest", "inside", "surface", "outside"])
def test_pose_kernel_is_libfrankas_filter_to_rounding(action_filter, n, regime):
    gen = CommandGenerator("cartesian_pose", action_filter, 40, n=n)
    assert gen._pose_kernel is not None
    rng = np.random.default_rng(7 * n + len(regime))
    for trial in range(150):
        state = _pose_state(rng, n, regime)
        action = rng.uniform(-1, 1, (n, 6)) * (0.0 if trial % 5 == 0 else 1.0)
        gen.begin_step(action, state)
        # the step's first cycle (the state where the step began), then a motion under way
        for now in (state, _moved(rng, state, 1e-3 if trial % 2 else 0.05)):
            fast = gen._pose_wire(now, 0)
            assert fast is gen._pose_out  # the kernel's answer, not the fallback's
            fast = fast.copy()
            reference = to_wire(gen._pose_command(now, 0))
            np.testing.assert_allclose(fast, reference, rtol=0, atol=POSE_ATOL, err_msg=trial)
            assert is_homogeneous(from_wire(fast)).all()


def _kernel_pose(T_c, T_ref, twist, dtwist, gain: float, rate_limit: bool) -> np.ndarray:
    out = np.full((1, 16), np.nan)
    limits = np.array(LIBFRANKA_LIMITS)
    ok = kernel.limit_pose(
        T_c[None], to_wire(T_ref[None]), np.array([twist], dtype=float),
        np.array([dtwist], dtype=float), gain, limits, rate_limit, out,
    )  # fmt: skip
    assert ok is True
    return from_wire(out)[0]


@pytest.mark.parametrize(("T_c", "T_last", "twist", "dtwist", "expected"), POSE_LIMITER_CASES)
def test_pose_kernel_limits_as_libfranka_does(T_c, T_last, twist, dtwist, expected):
    """Gain 1 (no low-pass): libfranka 0.21.2's limitRate values, computed with Eigen."""
    out = _kernel_pose(T_c, T_last, twist, dtwist, 1.0, True)
    np.testing.assert_allclose(out, expected, rtol=0, atol=POSE_ATOL)


@pytest.mark.parametrize(("T_c", "T_ref", "cutoff", "expected"), LOWPASS_CASES)
def test_pose_kernel_filters_as_libfranka_does(T_c, T_ref, cutoff, expected):
    """No rate limiter: libfranka 0.21.2's cartesianLowpassFilter values."""
    out = _kernel_pose(T_c, T_ref, [0.0] * 6, [0.0] * 6, cf.lowpass_gain(cutoff), False)
    np.testing.assert_allclose(out, expected, rtol=0, atol=POSE_ATOL)


@pytest.mark.parametrize(
    ("field", "index", "message"),
    [
        ("O_T_EE_c", 13, "T_ref: Cartesian lowpass-filter: current or past input value"),
        ("O_dP_EE_c", 2, "twist_last"),
        ("O_ddP_EE_c", 5, "dtwist_last"),
    ],
)
def test_a_non_finite_pose_input_takes_the_reference_path_and_its_error(field, index, message):
    gen = CommandGenerator("cartesian_pose", "limit_rate", 40)
    state = _pose_state(np.random.default_rng(1), 1, "inside")
    gen.begin_step(np.zeros((1, 6)), state)
    state[field][0, index] = np.inf
    out = np.full((1, 16), 7.0)
    args = (gen._target, state["O_T_EE_c"], state["O_dP_EE_c"], state["O_ddP_EE_c"])
    assert kernel.limit_pose(*args, gen._gain, gen._twist_limits, True, out) is False
    with pytest.raises(ValueError, match=message):
        gen._pose_wire(state, 0)


def test_a_reference_far_from_a_rotation_is_left_to_the_svd():
    """A state whose rotation is 30 % off orthonormal: Newton-Schulz has not converged in
    its three passes, the kernel declines, and the numpy path (SVD) gives the command."""
    gen = CommandGenerator("cartesian_pose", "limit_rate", 40)
    state = _pose_state(np.random.default_rng(2), 1, "inside")
    gen.begin_step(np.full((1, 6), 0.5), state)
    T = from_wire(state["O_T_EE_c"])
    T[:, :3, :3] *= 1.3
    state["O_T_EE_c"] = to_wire(T)
    args = (gen._target, state["O_T_EE_c"], state["O_dP_EE_c"], state["O_ddP_EE_c"])
    assert kernel.limit_pose(*args, gen._gain, gen._twist_limits, True, np.zeros((1, 16))) is False
    assert same_bits(gen._pose_wire(state, 0), to_wire(gen._pose_command(state, 0)))


def test_the_pose_kernel_names_a_bad_argument():
    T, wire, six, limits = (
        np.tile(np.eye(4), (2, 1, 1)),
        np.zeros((2, 16)),
        np.zeros((2, 6)),
        np.ones(6),
    )
    with pytest.raises(ValueError, match="ref: axis 0 has length 1, expected 2"):
        kernel.limit_pose(T, wire[:1], six, six, 1.0, limits, True, np.zeros((2, 16)))
    with pytest.raises(ValueError, match="ddref: axis 1 has length 5, expected 6"):
        kernel.limit_pose(T, wire, six, six[:, :5], 1.0, limits, True, np.zeros((2, 16)))
    with pytest.raises(ValueError, match="out: expected a 2-D float64 array"):
        kernel.limit_pose(T, wire, six, six, 1.0, limits, True, np.zeros((2, 16), np.float32))
    with pytest.raises(TypeError, match=r"limit_pose\(\) takes 8 arguments \(7 given\)"):
        kernel.limit_pose(T, wire, six, six, 1.0, limits, True)


@pytest.mark.parametrize("action_filter", ["lowpass", "limit_rate"])
def test_a_pose_episode_with_the_kernel_ends_as_the_reference_does(action_filter, monkeypatch):
    """End to end, 60 steps of random pose actions: the same rewards, cycles and errors
    step by step, and the end effector where the reference puts it.

    Not the same bits: the kernel's rounding differs from numpy's, and the limiter's
    loop through the float32 state amplifies that (one float32 ulp of O_T_EE_c is 6e-8 m,
    60 um/s once differentiated over 1 ms). The arm's null space is not commanded at all,
    so its joints wander apart by up to ~1e-3 rad over the episode while the end effector
    agrees to ~3e-7 m.
    """
    fast = rollout("cartesian_pose", action_filter, steps=60)
    joint_and_client_kernels_off(monkeypatch)
    reference = rollout("cartesian_pose", action_filter, steps=60)
    assert len(fast) == len(reference)
    np.testing.assert_array_equal(fast[2::2], reference[2::2])  # reward, cycles, errors
    ee = slice(14, 17)  # observation: q, dq, then O_T_EE's position
    for a, b in zip(fast[1::2], reference[1::2], strict=True):
        np.testing.assert_allclose(a[ee], b[ee], rtol=0, atol=1e-5)
    if action_filter == "lowpass":  # a naive stream: every episode ends in a reflex
        assert all(info[2] > 0 for info in fast[2::2])
    else:
        assert not any(info[2] for info in fast[2::2])  # the limiter keeps it clean
