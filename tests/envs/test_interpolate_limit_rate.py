"""The env client's ``"interpolate_limit_rate"`` filter (envs/commands.py): the step's
target interpolated across its cycles, then libfranka's low-pass and rate limiter.

What it is for: libfranka's limiter alone crosses a small change of the target at an
acceleration near ``sqrt(dv * jerk)`` (its whole jerk, then back), the ramp at about
``dv / step``; a large change is still bounded by the limiter's acceleration and jerk.
The commands are run against the robot's echo of them (O_dP_EE_c / O_ddP_EE_c, q_d /
dq_d / ddq_d), as ControlLoop reads them.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from franka_sim_gym.envs.commands import CARTESIAN_LIMITS, FILTERS, CommandGenerator
from franka_sim_gym.fci.tables import DELTA_T, FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE

CYCLES = 40  # 25 Hz
V_MAX, A_MAX, J_MAX = CARTESIAN_LIMITS["conservative"][:3]


def _twist_stream(action_filter: str, actions: list[np.ndarray]) -> np.ndarray:
    """The commanded twists of one step per action, each cycle's command echoed as the
    robot echoes it (O_dP_EE_c, and O_ddP_EE_c its backward difference)."""
    gen = CommandGenerator("cartesian_velocity", action_filter, CYCLES, cartesian_dof=3)
    state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
    out = []
    for a in actions:
        gen.begin_step(np.asarray(a, dtype=np.float64)[None], state)
        for k in range(CYCLES):
            v = gen.command(state, k).copy()
            state["O_ddP_EE_c"][0] = (v[0] - state["O_dP_EE_c"][0]) / DELTA_T
            state["O_dP_EE_c"][0] = v[0]
            out.append(v[0])
    return np.array(out)


def _acceleration(stream: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(stream[:, :3], axis=0), axis=1) / DELTA_T


def test_the_filter_is_offered_and_an_unknown_one_names_it():
    assert "interpolate_limit_rate" in FILTERS
    with pytest.raises(ValueError, match="interpolate_limit_rate"):
        CommandGenerator("cartesian_velocity", "hold", CYCLES)


def test_a_small_change_is_crossed_at_the_holds_acceleration_not_the_limiters():
    """0.1 m/s along x, then 2 mm/s more: under the limiter alone the change peaks near
    sqrt(dv * j) = 0.63 m/s^2; held, at dv / step = 0.05 m/s^2 (the low-pass smooths
    the first cycle's increment, not the peak)."""
    cruise = [np.array([1 / 3, 0.0, 0.0])] * 15  # 0.1 m/s at 0.3 m/s a unit action
    change = [np.array([0.102 / 0.3, 0.0, 0.0])] * 3
    dv = 0.002
    for name, bound in (("limit_rate", None), ("interpolate_limit_rate", dv / (CYCLES * DELTA_T))):
        stream = _twist_stream(name, cruise + change)
        peak = _acceleration(stream[15 * CYCLES - 1 :]).max()
        np.testing.assert_allclose(stream[-1, 0], 0.102, atol=1e-6)  # reached either way
        if bound is None:
            assert peak > 0.5 * np.sqrt(dv * J_MAX), peak
        else:
            assert peak <= bound * (1 + 1e-4), peak


def test_a_held_stream_stays_inside_the_limiters_bounds_for_any_action():
    """Random actions, large changes included: the limiter still bounds the held target
    (velocity, acceleration, jerk of the translation within the conservative limits)."""
    rng = np.random.default_rng(3)
    stream = _twist_stream("interpolate_limit_rate", list(rng.uniform(-1, 1, (25, 3))))
    v = np.linalg.norm(stream[:, :3], axis=1)
    a = np.diff(stream[:, :3], axis=0) / DELTA_T
    j = np.diff(a, axis=0) / DELTA_T
    assert v.max() <= V_MAX * (1 + 1e-9)
    assert np.linalg.norm(a, axis=1).max() <= A_MAX * (1 + 1e-5)
    assert np.linalg.norm(j, axis=1).max() <= J_MAX * (1 + 1e-4)  # (a second difference)
    assert np.linalg.norm(a, axis=1).max() > 0.9 * A_MAX  # the bound was reached


Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def _joint_stream(action_filter: str, steps: int) -> np.ndarray:
    """q_c of ``steps`` steps of 0.02 rad on every joint, after one step at rest (the
    motion's first command, its own reference, is behind it), echoed as q_d / dq_d /
    ddq_d."""
    gen = CommandGenerator("joint_position", action_filter, CYCLES)
    state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
    state["q_d"][0] = Q0
    qs = []
    for step in range(steps + 1):
        gen.begin_step(np.full((1, 7), 0.2 if step else 0.0), state)
        for k in range(CYCLES):
            q = gen.command(state, k).copy()[0]
            dq = (q - state["q_d"][0]) / DELTA_T
            state["ddq_d"][0] = (dq - state["dq_d"][0]) / DELTA_T
            state["dq_d"][0] = dq
            state["q_d"][0] = q
            qs.append(q)
    return np.array(qs)


def test_a_joint_position_step_is_held_then_limited():
    """Joint position: the commands follow the interpolation toward each step's target
    (the low-pass and limiter behind it), and the limiter still bounds them: the ramp
    from rest is a step of 0.5 rad/s, which it crosses at its acceleration target."""
    qs = _joint_stream("interpolate_limit_rate", 4)
    ddq = np.diff(qs, n=2, axis=0) / DELTA_T**2
    assert np.abs(ddq).max() <= FR3.ddq_max.min()
    assert np.abs(ddq).max() > 0.9 * FR3.ddq_max.min()  # (reached)
    # Four offsets of 0.02 rad, each from the step's q_d (the action is an offset from
    # it, as under "limit_rate"): the joints have moved 0.08 rad, less the filters' lag.
    moved = qs[-1] - Q0
    assert (moved > 0.06).all() and (moved <= 0.08).all(), moved


def _push_trace(action_filter: str) -> np.ndarray:
    """Push's observations over five steps of small random actions (seed 7)."""
    env = gym.make("FrankaFCIPush-v0", action_filter=action_filter)
    obs, _ = env.reset(seed=7)
    trace = [obs["observation"].copy()]
    rng = np.random.default_rng(0)
    for _ in range(5):
        action = 0.03 * rng.uniform(-1, 1, env.action_space.shape)  # under the limiter's a
        obs, *_ = env.step(action.astype(np.float32))
        trace.append(obs["observation"].copy())
    env.close()
    return np.array(trace)


def test_the_env_runs_the_filter_and_repeats_itself():
    """Push under the ramp: the same seed and actions, the same observations, bit for
    bit; not those of the limiter alone; and from the second step on (the first starts
    the motion from rest) each step's commanded twist (the observation's O_dP_EE_c)
    arrives at the step's target, less the low-pass's lag behind a ramp (1.6 ms of a
    40 ms ramp: 4 % of the change)."""
    ramped = _push_trace("interpolate_limit_rate")
    assert np.array_equal(
        ramped.view(np.uint32), _push_trace("interpolate_limit_rate").view(np.uint32)
    )
    assert not np.array_equal(ramped, _push_trace("limit_rate"))
    rng = np.random.default_rng(0)
    targets = 0.03 * rng.uniform(-1, 1, (5, 3)) * 0.3  # m/s: 0.3 m/s a unit action
    change = np.abs(np.diff(targets, axis=0))
    assert (np.abs(ramped[2:, 17:20] - targets[1:]) <= 0.05 * change + 1e-6).all()
