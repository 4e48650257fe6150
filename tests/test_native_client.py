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
from franka_sim_gym.envs.commands import CommandGenerator
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE
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


@pytest.mark.parametrize("interface", ["joint_position", "joint_velocity", "cartesian_velocity"])
def test_an_episode_is_the_same_with_and_without_the_kernels(interface, monkeypatch):
    """End to end, random actions through libfranka's limiters (reflexes included): the
    joint rules' and the client's kernels change no bit of what a policy sees."""
    fast = rollout(interface, "limit_rate")
    joint_and_client_kernels_off(monkeypatch)
    reference = rollout(interface, "limit_rate")
    assert len(fast) == len(reference)
    for a, b in zip(fast, reference, strict=True):
        assert same_bits(a, b)
