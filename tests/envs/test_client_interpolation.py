"""The env client's interpolation between two policy steps (envs/client_filters.py
``interpolate``): both ends exact, monotone, the cosine profile, refusals, and the
per-cycle core bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.envs import client_filters as cf


@pytest.mark.parametrize("kind", ["linear", "cosine"])
def test_interpolate_hits_both_ends_exactly_and_is_monotone(kind):
    rng = np.random.default_rng(5)
    q0, q1 = rng.normal(size=(3, 7)), rng.normal(size=(3, 7))
    assert np.array_equal(cf.interpolate(q0, q1, 0.0, kind), q0)
    assert np.array_equal(cf.interpolate(q0, q1, 1.0, kind), q1)
    path = np.array([cf.interpolate(q0, q1, a, kind) for a in np.linspace(0, 1, 21)])
    steps = np.diff(path, axis=0) * np.sign(q1 - q0)
    assert (steps >= -1e-15).all()


def test_interpolate_cosine_profile_and_per_robot_alpha():
    q0, q1 = np.zeros((2, 7)), np.ones((2, 7))
    np.testing.assert_allclose(cf.interpolate(q0, q1, 0.5, "cosine"), 0.5)
    np.testing.assert_allclose(
        cf.interpolate(q0, q1, 0.25, "cosine"), 0.5 * (1 - math.cos(math.pi / 4))
    )
    out = cf.interpolate(q0, q1, np.array([[0.25], [0.75]]))
    np.testing.assert_allclose(out[:, 0], [0.25, 0.75])


def test_interpolate_rejects_unknown_kind_and_alpha_out_of_range():
    z = np.zeros((1, 7))
    with pytest.raises(ValueError, match="unknown interpolation kind 'cubic'"):
        cf.interpolate(z, z, 0.5, "cubic")
    for alpha in (-0.1, 1.5, math.nan):
        with pytest.raises(ValueError, match=r"alpha must be finite and in \[0, 1\]"):
            cf.interpolate(z, z, alpha)


def test_interpolate_core_is_interpolates_arithmetic_bit_for_bit():
    """The env's per-cycle call: every phase of a 40-cycle step, wide-ranging ends."""
    rng = np.random.default_rng(4)
    q0, q1 = rng.normal(0, 10, (16, 7)), rng.normal(0, 10, (16, 7))
    for k in range(40):
        s = (k + 1) / 40
        core, public = cf.interpolate_core(q0, q1, s), cf.interpolate(q0, q1, s)
        assert np.array_equal(core.view(np.uint64), public.view(np.uint64)), k
    assert np.array_equal(cf.interpolate_core(q0, q1, 1.0), q1)


@pytest.mark.parametrize("interface", ["joint_position", "torque", "cartesian_velocity"])
def test_an_interpolated_step_checks_its_ends_once_at_its_start(interface):
    """The client validates a step's ends in begin_step (then interpolates unchecked):
    a non-finite state is refused there, with interpolate's error."""
    from franka_sim_gym.envs.commands import CommandGenerator
    from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE

    gen = CommandGenerator(interface, "interpolate", 40)
    state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
    field = {"joint_position": "q_d", "torque": "tau_J_d"}.get(interface, "O_dP_EE_c")
    state[field][0, 2] = np.nan
    with pytest.raises(ValueError, match="q_from"):
        gen.begin_step(np.zeros((1, gen.action_dim)), state)
