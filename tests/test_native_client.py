"""The env client's Cartesian velocity kernel (native/_client.c) against its numpy
reference, bit for bit: libfranka's low-pass filter and twist rate limiter.

States sweep the corners of the norm limiter: at rest (no jerk, no acceleration),
inside the velocity ball, at its surface and outside it (the square root's negative
argument), and jerks far past the limit, on both halves of the twist.
"""

from __future__ import annotations

import numpy as np
import pytest

import franka_sim_gym.envs.commands as commands_module
import franka_sim_gym.fci.engine as engine_module
import franka_sim_gym.fci.tables as tables_module
from franka_sim_gym import native
from franka_sim_gym.envs.commands import CommandGenerator
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE
from tests.test_native_joint import _rollout, same_bits

kernel = native.load("_client")
pytestmark = pytest.mark.skipif(kernel is None, reason="native/_client.c not built")


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


def test_a_cartesian_velocity_episode_is_the_same_with_and_without_the_kernels(monkeypatch):
    fast = _rollout("cartesian_velocity", "limit_rate")
    monkeypatch.setattr(commands_module, "CLIENT_KERNEL", None)
    for module in (tables_module, engine_module, commands_module):
        monkeypatch.setattr(module, "JOINT_KERNEL", None)
    reference = _rollout("cartesian_velocity", "limit_rate")
    assert len(fast) == len(reference)
    for a, b in zip(fast, reference, strict=True):
        assert same_bits(a, b)
