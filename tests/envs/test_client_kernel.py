"""envs/_client_filters.c, the one text of the client's filter rules (envs/client_kernel.py):
what the public functions' tests (test_client_filters.py, test_cartesian_*.py) do not reach.
Each robot reads its own gain and limits (the env passes broadcast views of one value; a
user may pass one per robot), an acceleration that rounds to nothing leaves the twist as
it was, and a bad argument is named."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.envs import cartesian_filters as cc
from franka_sim_gym.envs import client_filters as cf
from franka_sim_gym.envs.client_kernel import RULES
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE
from franka_sim_gym.sim.rotations import rotation_exp
from tests.cartesian_filter_helpers import LIMITS, random_pose

#: The conservative Cartesian limits the env uses by default (commands.CARTESIAN_LIMITS).
TWIST_LIMITS = (0.5, 1.0, 200.0, 1.0, 2.0, 400.0)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a.view(np.uint64), b.view(np.uint64)))


def test_each_robot_is_low_passed_with_its_own_cutoff():
    rng = np.random.default_rng(0)
    x, ref = rng.normal(size=(3, 7)), rng.normal(size=(3, 7))
    cutoffs = np.array([[10.0], [100.0], [500.0]])
    batch = cf.lowpass_filter(x, ref, cutoffs)
    for i in range(3):
        assert _same(batch[i], cf.lowpass_filter(x[i], ref[i], float(cutoffs[i, 0])))
    assert not np.allclose(batch[0], batch[2])
    # one cutoff per joint too: every element its own gain
    per_joint = rng.uniform(5.0, 900.0, (3, 7))
    batch = cf.lowpass_filter(x, ref, per_joint)
    for i in range(3):
        for j in range(7):
            alone = cf.lowpass_filter(x[i, j], ref[i, j], per_joint[i, j])
            assert _same(np.atleast_1d(batch[i, j]), np.atleast_1d(alone))


def test_each_robot_and_joint_is_rate_limited_with_its_own_limits():
    rng = np.random.default_rng(1)
    dq_c, dq, ddq = rng.normal(size=(2, 7)), rng.normal(size=(2, 7)), rng.normal(size=(2, 7))
    upper, lower = np.full((2, 7), 2.0), np.full((2, 7), -2.0)
    a_max = np.stack([FR3.ddq_max, 0.5 * FR3.ddq_max])
    j_max = np.stack([FR3.dddq_max, 0.1 * FR3.dddq_max])
    batch = cf.limit_rate_joint_velocities(dq_c, dq, ddq, upper, lower, a_max, j_max)
    for i in range(2):
        one = cf.limit_rate_joint_velocities(
            dq_c[i], dq[i], ddq[i], upper[i], lower[i], a_max[i], j_max[i]
        )
        assert _same(batch[i], one)
    tau_c, tau = rng.normal(0, 5, (2, 7)), np.zeros((2, 7))
    rates = np.array([[1000.0] * 7, [10.0, 20, 30, 40, 50, 60, 70]])
    limited = cf.limit_rate_torques(tau_c, tau, rates)
    # every joint of the second robot at its own rate (|tau_c| / 1 ms >> 70 Nm/s)
    np.testing.assert_allclose(np.abs(limited[1]), rates[1] * 1e-3, rtol=1e-12)
    assert _same(limited[0], cf.limit_rate_torques(tau_c[0], tau[0], 1000.0))


def test_each_robot_gets_its_own_cartesian_limits_and_cutoff():
    rng = np.random.default_rng(2)
    twist_c = rng.normal(size=(2, 6))
    zero = np.zeros((2, 6))
    # one set of limits per robot; the jerk limits bind (from rest), on both halves
    limits = [np.array([x, 0.1 * x]) for x in LIMITS]
    batch = cc.limit_rate_cartesian_velocity(twist_c, zero, zero, *limits)
    for i in range(2):
        mine = [x[i] for x in limits]
        alone = cc.limit_rate_cartesian_velocity(twist_c[i], zero[i], zero[i], *mine)
        assert _same(batch[i], alone)
    assert not np.allclose(batch[0], batch[1])
    T_c = np.stack([random_pose(rng) for _ in range(2)])
    T_last = T_c.copy()
    T_last[:, :3, 3] -= 0.01
    T_last[:, :3, :3] = rotation_exp(np.array([0.03, -0.02, 0.05])) @ T_c[:, :3, :3]
    poses = cc.limit_rate_cartesian_pose(T_c, T_last, zero, zero, *limits)
    lowpassed = cc.cartesian_lowpass_filter(T_c, T_last, np.array([10.0, 500.0]))
    for i in range(2):
        mine = [x[i] for x in limits]
        alone = cc.limit_rate_cartesian_pose(T_c[i], T_last[i], zero[i], zero[i], *mine)
        assert _same(poses[i], alone)
        alone = cc.cartesian_lowpass_filter(T_c[i], T_last[i], [10.0, 500.0][i])
        assert _same(lowpassed[i], alone)


def test_an_acceleration_that_rounds_to_nothing_leaves_the_twist_as_it_was():
    """At rest with a last acceleration of ~1e-13: the jerk takes it back to |a| <= eps,
    where libfranka returns v_last itself (its kNormEps branch)."""
    rng = np.random.default_rng(2)
    limits = np.broadcast_to(np.array(TWIST_LIMITS), (16, 6))
    for _ in range(50):
        state = np.zeros(16, dtype=ROBOT_STATE_DTYPE)
        state["O_ddP_EE_c"] = rng.normal(0, 1e-13, (16, 6))
        out = np.full((16, 6), np.nan)
        RULES.limit_twist(np.zeros((16, 6)), state["O_dP_EE_c"], state["O_ddP_EE_c"], limits, out)
        assert not out.any()


def test_the_c_text_names_a_bad_argument():
    six, limits = np.zeros((2, 6)), np.ones((2, 6))
    with pytest.raises(ValueError, match="^twist_last: axis 0 has length 1, expected 2"):
        RULES.limit_twist(six, six[:1], six, limits, np.zeros((2, 6)))
    with pytest.raises(ValueError, match="^out: expected a 2-D float64 array"):
        RULES.limit_twist(six, six, six, limits, np.zeros((2, 6)).astype(int))
    seven = np.zeros((2, 7))
    with pytest.raises(ValueError, match="^a_max: axis 1 has length 6, expected 7"):
        RULES.limit_velocities(seven, seven, seven, seven, seven, np.ones((2, 6)), seven, seven)
    with pytest.raises(TypeError, match=r"limit_torques\(\) takes 4 arguments \(3 given\)"):
        RULES.limit_torques(seven, seven, seven)
    with pytest.raises(ValueError, match="^gain: axis 0 has length 1, expected 2"):
        RULES.lowpass(seven, seven, np.ones((1, 7)), seven)
    T, wire = np.tile(np.eye(4), (2, 1, 1)), np.zeros((2, 16))
    with pytest.raises(ValueError, match="^dtwist_last: axis 1 has length 5, expected 6"):
        RULES.limit_pose(T, T, six, six[:, :5], limits, np.zeros((2, 4, 4)))
    with pytest.raises(ValueError, match="^out: expected a 3-D float64 array"):
        RULES.reference_pose(wire, np.zeros((2, 16)))
    poses = np.tile(np.eye(4), (6, 1, 1))
    with pytest.raises(ValueError, match=r"^cutoff must be one value or one per pose \(shape"):
        cc.cartesian_lowpass_filter(poses, poses, np.full((6, 1), 100.0))
    twist = np.zeros((6, 6))
    per_robot = [np.full((6, 1), x) for x in TWIST_LIMITS]  # an (n, 1) would add poses
    with pytest.raises(ValueError, match=r"^the limits must be one value or one per pose"):
        cc.limit_rate_cartesian_velocity(twist, twist, twist, *per_robot)


def test_the_joint_rules_take_any_shapes_that_broadcast():
    """The joint and torque rules treat each value on its own: a scalar, three joints, or
    (n, 7), each element as the (n, 7) batch computes it."""
    rng = np.random.default_rng(3)
    tau_c, tau_last = rng.normal(0, 5, (2, 7)), rng.normal(0, 5, (2, 7))
    batch = cf.limit_rate_torques(tau_c, tau_last, 1000.0)
    alone = cf.limit_rate_torques(float(tau_c[1, 4]), float(tau_last[1, 4]), 1000.0)
    assert isinstance(alone, np.float64) and alone == batch[1, 4]
    v = cf.limit_rate_joint_velocities(tau_c[:, :3], tau_last[:, :3], 0.0, 2.0, -2.0, 10.0, 5e3)
    full = cf.limit_rate_joint_velocities(tau_c, tau_last, 0.0, 2.0, -2.0, 10.0, 5e3)
    assert v.shape == (2, 3) and _same(v, np.ascontiguousarray(full[:, :3]))
    assert cf.lowpass_filter(np.zeros((2, 0)), np.zeros((2, 0))).shape == (2, 0)


def _joint_cycle_inputs(n: int = 5, seed: int = 2):
    """A joint-position cycle of n robots as the env's client meets it: float32 state
    fields, some joints near their stops (the band binds), a target 0.02 rad ahead."""
    rng = np.random.default_rng(seed)
    state = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
    q = rng.uniform(FR3.q_lower + 0.3, FR3.q_upper - 0.3, (n, 7))
    q[0] = FR3.q_upper - 1e-3  # at the upper stops: the band shuts
    state["q_d"], state["dq_d"] = q, rng.normal(scale=0.3, size=(n, 7))
    state["ddq_d"] = rng.normal(scale=2.0, size=(n, 7))
    state["dq_d"][0], state["ddq_d"][0] = 0.0, 0.0  # at rest there
    target = state["q_d"].astype(np.float64) + 0.02
    state["dq_d"][1], state["ddq_d"][1] = 0.0, 0.0  # at rest, 1 urad behind its target:
    target[1] = state["q_d"][1] + 1e-6  # the limiter passes what the low-pass gives it
    return state, target


def _joint_cycle(state, target, first, positions=True, limited=True):
    from franka_sim_gym.envs.commands import LIMITER_MARGIN
    from franka_sim_gym.fci.tables import JOINT_VELOCITY_LIMIT_TOLERANCE

    n = len(state)
    gain = np.broadcast_to(cf.lowpass_gain(cf.LOWPASS_DEFAULT_CUTOFF), (n, 7))
    a_max = np.broadcast_to(FR3.ddq_max - LIMITER_MARGIN["ddq"], (n, 7))
    j_max = np.broadcast_to(FR3.dddq_max - LIMITER_MARGIN["dddq"], (n, 7))
    shift = JOINT_VELOCITY_LIMIT_TOLERANCE + LIMITER_MARGIN["dq"]
    out = np.zeros((n, 7))
    fields = state["q_d"], state["dq_d"], state["ddq_d"]
    constants, positional = FR3.joint_constants
    args = (gain, constants, positional, shift, a_max, j_max, out)
    result = RULES.JointClient(positions, limited, *fields, *args).cycle(target, first)
    return result, (gain, a_max, j_max, shift)


def test_the_joint_position_cycle_is_the_low_pass_band_and_limiter_in_one_call():
    """The env's one call a cycle gives the bits of libfranka's steps one after the other
    (the low-pass against q_d, or against the target itself on a motion's first command;
    the band at q_d; the limiter), and the band binds: a robot at rest at its stops,
    its target beyond them, is turned back."""
    state, target = _joint_cycle_inputs()
    first = np.array([False, True, False, False, True])
    fused, (gain, a_max, j_max, shift) = _joint_cycle(state, target, first)
    q_d = state["q_d"]
    ref = np.where(first[:, None], target, q_d)
    x = RULES.lowpass(target, ref, gain, np.zeros((5, 7)))
    band = FR3.velocity_envelope_halves(q_d.astype(np.float64), shift)
    upper, lower = band[:, :7], -band[:, 7:]
    alone = RULES.limit_positions(
        x, q_d, state["dq_d"], state["ddq_d"], upper, lower, a_max, j_max, np.zeros((5, 7))
    )
    assert _same(fused, alone)
    assert (upper[0] < 0).all() and (target[0] > q_d[0]).all()  # shut; the target beyond
    assert (fused[0] < q_d[0]).all()
    unshut, _ = _joint_cycle(state, target, None)  # robot 1 now filtered against q_d
    assert not _same(unshut[1], fused[1]) and _same(unshut[2], fused[2])


def test_the_joint_velocity_cycle_is_its_low_pass_band_and_limiter_in_one_call():
    """A velocity command: low-passed against dq_d (a velocity motion has no first-command
    rule: ``first`` is not read), limited inside the band at q_d; the same bits as the
    steps one after the other."""
    state, _ = _joint_cycle_inputs()
    rng = np.random.default_rng(8)
    target = rng.uniform(-1.0, 1.0, (5, 7))
    first = np.array([True, True, False, False, True])
    fused, (gain, a_max, j_max, shift) = _joint_cycle(state, target, first, positions=False)
    x = RULES.lowpass(target, state["dq_d"], gain, np.zeros((5, 7)))
    band = FR3.velocity_envelope_halves(state["q_d"].astype(np.float64), shift)
    alone = RULES.limit_velocities(
        x, state["dq_d"], state["ddq_d"], band[:, :7], -band[:, 7:], a_max, j_max,
        np.zeros((5, 7)),
    )  # fmt: skip
    assert _same(fused, alone)
    assert _same(fused, _joint_cycle(state, target, None, positions=False)[0])


def test_unlimited_the_joint_cycle_is_the_low_pass_alone():
    """The "lowpass" filter's cycle: a position against q_d (against the target itself on
    a motion's first command), a velocity against dq_d, and nothing after."""
    state, target = _joint_cycle_inputs()
    first = np.array([False, True, False, False, True])
    gain = _joint_cycle(state, target, first)[1][0]
    fused = _joint_cycle(state, target, first, limited=False)[0]
    ref = np.where(first[:, None], target, state["q_d"])
    assert _same(fused, RULES.lowpass(target, ref, gain, np.zeros((5, 7))))
    assert not _same(fused, _joint_cycle(state, target, first)[0])  # the limiter binds
    velocity = _joint_cycle(state, target, first, positions=False, limited=False)[0]
    assert _same(velocity, RULES.lowpass(target, state["dq_d"], gain, np.zeros((5, 7))))


def test_the_joint_position_cycle_names_a_bad_argument():
    state, target = _joint_cycle_inputs()
    with pytest.raises(ValueError, match="first"):
        _joint_cycle(state, target, np.zeros(4, dtype=bool))
    with pytest.raises(ValueError, match="target: axis 0 has length 5, expected 4"):
        _joint_cycle(state[:4], target, None)  # the plan is for the state's 4 robots
    gain, a_max, j_max, shift = _joint_cycle(state, target, None)[1]
    constants, positional = FR3.joint_constants
    with pytest.raises(ValueError, match="q_d: axis 0 has length 4, expected 5"):
        RULES.JointClient(True, True, state["q_d"][:4], state["dq_d"], state["ddq_d"], gain,
                          constants, positional, shift, a_max, j_max, np.zeros((5, 7)))  # fmt: skip
