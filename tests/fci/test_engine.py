"""The engine's fused fast path decides exactly as the rule functions do."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci import limits
from franka_sim_gym.fci.tables import FER, FR3, INTERIOR_SPEED, JOINT_VELOCITY_LIMIT_TOLERANCE
from tests.fci_helpers import IMP, JP, LoopClient, make_controller

CTRL = make_controller()
LoopClient(CTRL).start(JP, IMP)
ENGINE = CTRL.engine
TABLE = CTRL.table


#: One joint's motion around mid-range: its q, and the velocity, acceleration and jerk
#: its next command implies (past every limit at the ends of each range).
JOINT_MOTION = dict(
    joint=st.integers(0, 6),
    q_offset=st.floats(-3.2, 3.2),
    velocity=st.floats(-3.0, 3.0),
    acceleration=st.floats(-12.0, 12.0),
    jerk=st.floats(-6000.0, 6000.0),
)


def _reference(joint=None, q_offset=0.0, velocity=0.0, acceleration=0.0, jerk=0.0):
    """Robot 0's reference at mid-range and at rest, but for ``joint``: at ``q_offset``
    (clipped to 5 cm past its stops), with the history from which a command at
    ``velocity`` implies ``acceleration`` and ``jerk``."""
    dt = 1e-3
    ref = CTRL.reference
    ref.q[0] = np.clip(TABLE.q_lower + (TABLE.q_upper - TABLE.q_lower) / 2 + 0.0, -3, 4)
    ref.dq[0] = 0.0
    ref.ddq[0] = 0.0
    if joint is not None:
        lo, hi = TABLE.q_lower[joint] - 0.05, TABLE.q_upper[joint] + 0.05
        ref.q[0, joint] = np.clip(q_offset, lo, hi)
        ref.dq[0, joint] = velocity - acceleration * dt
        ref.ddq[0, joint] = acceleration - jerk * dt
    return ref


@settings(max_examples=300, deadline=None)
@given(**JOINT_MOTION)
def test_fast_path_agrees_with_check_joint_position(joint, q_offset, velocity, acceleration, jerk):
    dt = 1e-3
    ref = _reference(joint, q_offset, velocity, acceleration, jerk)
    q_c = ref.q.copy()
    q_c[0, joint] += velocity * dt
    fast = ENGINE._positions_inside_limits(q_c)
    rule = limits.check_joint_position(
        q_c, ref.q, ref.dq, ref.ddq, False, ref.q, 1, TABLE, 0.1
    ).error
    assert fast == (rule[0] == limits.NO_ERROR)


@settings(max_examples=300, deadline=None)
@given(**JOINT_MOTION)
def test_velocity_fast_path_agrees_with_check_joint_velocity(
    joint, q_offset, velocity, acceleration, jerk
):
    ref = _reference(joint, q_offset, velocity, acceleration, jerk)
    dq_c = ref.dq.copy()
    dq_c[0, joint] = velocity
    fast = ENGINE._velocities_inside_limits(dq_c)
    rule = limits.check_joint_velocity(dq_c, ref.q, ref.dq, ref.ddq, False, ref.dq, 1, TABLE, 0.1)
    assert fast == (rule.error[0] == limits.NO_ERROR)
    # the acceleration it leaves is the one the general path records
    assert np.array_equal(ENGINE._velocity_ddq, rule.ddq)


@pytest.mark.parametrize("factor", [0.999, 1.0 - 1e-9, 1.0 + 1e-9, 1.005])
@pytest.mark.parametrize("row", ["acceleration", "jerk", "envelope"])
def test_velocity_fast_path_at_each_limits_edge(row, factor):
    """Just inside and just past each row's limit, the fast path decides as the rule."""
    dt = 1e-3
    ref = _reference()
    dq_c = ref.dq.copy()
    if row == "acceleration":  # ddq at the limit, no jerk
        ref.ddq[0, 3] = TABLE.ddq_max[3] * factor
        ref.dq[0, 3] = 0.2
        dq_c[0, 3] = 0.2 + ref.ddq[0, 3] * dt
    elif row == "jerk":  # dddq at the limit, from rest
        dq_c[0, 3] = TABLE.dddq_max[3] * factor * dt * dt
    else:  # dq_c at the envelope's upper edge at q_d, reached at a small acceleration
        upper, _ = TABLE.velocity_envelope(ref.q)
        dq_c[0, 3] = upper[0, 3] * factor
        ref.dq[0, 3] = dq_c[0, 3] - 1e-3 * dt
        ref.ddq[0, 3] = -1e-3
    fast = ENGINE._velocities_inside_limits(dq_c)
    rule = limits.check_joint_velocity(dq_c, ref.q, ref.dq, ref.ddq, False, ref.dq, 1, TABLE, 0.1)
    assert fast == (rule.error[0] == limits.NO_ERROR)
    if factor > 1.001:
        assert not fast
    if factor < 0.9999:
        assert fast


@settings(max_examples=300, deadline=None)
@given(
    joint=st.integers(0, 6),
    tau_prev=st.floats(-100.0, 100.0),
    rate=st.floats(-1200.0, 1200.0),
)
def test_torque_fast_path_agrees_with_check_torque(joint, tau_prev, rate):
    """Rows 34 (|tau| past the joint's effort limit at the ends) and 32 (the rate)."""
    tau_J_d = CTRL.tau_J_d
    kept = tau_J_d.copy()
    try:
        tau_J_d[...] = 0.0
        tau_J_d[0, joint] = tau_prev
        tau_c = tau_J_d.copy()
        tau_c[0, joint] = tau_prev + rate * 1e-3
        fast = ENGINE._torques_inside_limits(tau_c)
        rule = limits.check_torque(tau_c, tau_J_d.copy(), np.zeros(1, bool), 1, TABLE)
        assert fast == (rule[0] == limits.NO_ERROR)
    finally:
        tau_J_d[...] = kept


@pytest.mark.parametrize("factor", [0.999, 1.0 - 1e-9, 1.0 + 1e-9, 1.005])
@pytest.mark.parametrize("row", ["range", "rate"])
def test_torque_fast_path_at_each_limits_edge(row, factor):
    tau_J_d = CTRL.tau_J_d
    kept = tau_J_d.copy()
    try:
        tau_J_d[...] = 0.0
        tau_c = np.zeros_like(tau_J_d)
        if row == "range":  # at the effort limit, reached at a small rate
            tau_c[0, 5] = TABLE.tau_max[5] * factor
            tau_J_d[0, 5] = tau_c[0, 5] - 0.1
        else:  # from zero at the rate limit
            tau_c[0, 5] = TABLE.dtau_max * factor * 1e-3
        fast = ENGINE._torques_inside_limits(tau_c)
        rule = limits.check_torque(tau_c, tau_J_d.copy(), np.zeros(1, bool), 1, TABLE)
        assert fast == (rule[0] == limits.NO_ERROR)
        if factor > 1.001:
            assert not fast
        if factor < 0.9999:
            assert fast
    finally:
        tau_J_d[...] = kept


def _rollout(interface: str, action_filter: str, amplitude: float, seed: int) -> list:
    """Steps, resets and the robot's own history after each step (what the next cycles
    are judged against): the joint reference, or for torques the applied tau_J_d."""
    import gymnasium as gym

    import franka_sim_gym  # noqa: F401  (registers the ids)

    env = gym.make(
        "FrankaFCI-v0",
        action_interface=interface,
        action_filter=action_filter,
        max_episode_steps=30,
    )
    rng = np.random.default_rng(seed)
    out = [env.reset(seed=seed)]
    ctrl = env.unwrapped.controller
    ref = ctrl.reference
    for _ in range(90):
        step = env.step(rng.uniform(-amplitude, amplitude, size=7).astype(np.float32))
        out.append(step)
        if interface == "torque":
            out.append(("tau_J_d", {"tau_J_d": ctrl.tau_J_d.copy()}))
        else:
            history = ("q", "dq", "ddq", "ddq_frozen", "run")
            out.append(("reference", {k: getattr(ref, k).copy() for k in history}))
        if step[2] or step[3]:
            out.append(env.reset())
    env.close()
    return out


@pytest.mark.parametrize(
    "interface, fast_path_name, action_filter, amplitude, fast_cycles",
    # unfiltered: steps small enough to start a motion (0.1 rad/s; 1 Nm), then each change
    # of step trips a discontinuity mid-motion (joint acceleration; torque rate, 32)
    [
        ("joint_velocity", "_velocities_inside_limits", "limit_rate", 1.0, 3000),
        ("joint_velocity", "_velocities_inside_limits", "none", 0.05, 100),
        ("torque", "_torques_inside_limits", "limit_rate", 1.0, 3000),
        ("torque", "_torques_inside_limits", "none", 0.05, 30),
    ],
)
def test_fast_path_episodes_are_the_general_paths_bit_for_bit(
    interface, fast_path_name, action_filter, amplitude, fast_cycles, monkeypatch
):
    """Whole episodes (reflexes and resets included) through a fast path equal the same
    episodes with every cycle sent down the rule functions' general path."""
    from franka_sim_gym.fci.engine import MotionLimitEngine

    fast_path = getattr(MotionLimitEngine, fast_path_name)
    passed = []

    def counted(self, command):
        passed.append(fast_path(self, command))
        return passed[-1]

    monkeypatch.setattr(MotionLimitEngine, fast_path_name, counted)
    fast = _rollout(interface, action_filter, amplitude, seed=4)
    assert sum(passed) > fast_cycles  # the fast path decided most cycles
    if action_filter == "none":  # the jumps it refused went down the general path
        assert not all(passed)
        assert any(x[2] and x[4]["reflex_reason"] for x in fast if len(x) == 5)
    monkeypatch.setattr(MotionLimitEngine, fast_path_name, lambda self, command: False)
    general = _rollout(interface, action_filter, amplitude, seed=4)
    assert len(fast) == len(general)
    for a, b in zip(fast, general, strict=True):
        assert repr(a) == repr(b)
        for x, y in zip(a, b, strict=True):
            if isinstance(x, dict):
                for key in x:
                    assert np.array_equal(np.asarray(x[key]), np.asarray(y[key])), key


@settings(max_examples=100, deadline=None)
@given(answers=st.lists(st.booleans(), min_size=1, max_size=260))
def test_one_robot_accounting_matches_the_batched_arithmetic(answers):
    from franka_sim_gym.fci.accounting import CycleAccounting

    one, two = CycleAccounting(1), CycleAccounting(2)  # n = 2 takes the array path
    for acc in (one, two):
        acc.start_motion(0, 0)
        acc.started[0] = True
    for answered in answers:
        one.answered[0] = two.answered[0] = answered
        one.close_cycle(1)
        two.close_cycle(1)
        assert one.success_rate()[0] == two.success_rate()[0]
        assert one.lost_run[0] == two.lost_run[0]
        assert one.longest_lost_run[0] == two.longest_lost_run[0]
        assert one.lost_total[0] == two.lost_total[0]


def _interior_edges(table):
    distance = (INTERIOR_SPEED + table.dq_offset) ** 2 / (2.0 * table.ddq_decel)
    return table.q_upper - distance, table.q_lower + distance


@pytest.mark.parametrize("robot", [FR3, FER], ids=["fr3", "fer"])
@pytest.mark.parametrize(
    "shift", [JOINT_VELOCITY_LIMIT_TOLERANCE, JOINT_VELOCITY_LIMIT_TOLERANCE - 0.1]
)
def test_interior_shortcut_never_passes_a_speed_the_envelope_refuses(robot, shift):
    # The hardest case for the shortcut: the largest speed it lets through, at every q
    # it accepts, on a fine grid across the joint's range and at the interior's edges
    # and their float neighbours.
    bounds = robot.interior_bounds(INTERIOR_SPEED, shift)
    grids = [
        np.linspace(lo - 0.05, hi + 0.05, 4001)
        for lo, hi in zip(robot.q_lower, robot.q_upper, strict=True)
    ]
    if robot.dq_offset is not None:
        upper_edge, lower_edge = _interior_edges(robot)
        for j in range(7):
            around = np.concatenate(
                [upper_edge[j] + np.arange(-3, 4) * 1e-16, lower_edge[j] + np.arange(-3, 4) * 1e-16]
            )
            grids[j] = np.concatenate(
                [grids[j], np.nextafter(around, np.inf), np.nextafter(around, -np.inf), around]
            )
    checked = 0
    for j in range(7):
        q = np.tile((robot.q_lower + robot.q_upper) / 2, (len(grids[j]), 1))
        q[:, j] = grids[j]
        for sign, limit in ((1.0, bounds[j]), (-1.0, bounds[14 + j])):
            velocity = np.zeros_like(q)
            velocity[:, j] = sign * limit
            x = np.concatenate([velocity, q, -velocity, -q], axis=1)
            accepted = (x <= bounds).all(axis=1)
            exact = np.concatenate([velocity, -velocity], axis=1) <= robot.velocity_envelope_halves(
                q, shift
            )
            assert exact[accepted].all()
            checked += int(accepted.sum())
    assert checked > 10_000  # the shortcut accepts most of each range


def test_interior_shortcut_covers_the_home_pose_at_a_joint_speed_of_1_4_rad_per_s():
    # The shortcut is worth its place only if it decides the common case: a motion
    # around the home pose (spec) at the speeds the examples reach.
    home = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
    velocity = np.full(7, 1.4)
    for shift in (JOINT_VELOCITY_LIMIT_TOLERANCE, JOINT_VELOCITY_LIMIT_TOLERANCE - 0.1):
        bounds = FR3.interior_bounds(INTERIOR_SPEED, shift)
        assert (np.concatenate([velocity, home, -velocity, -home]) <= bounds).all()


def test_ee_speed_shortcut_never_passes_a_speed_over_the_limit():
    # The safety controller's per-axis bound on the measured EE velocity (for 4): the
    # largest vector it lets through, (c, +-c, +-c), is within kMaxTranslationalVelocity.
    bounds = ENGINE._measured_bounds
    axis = bounds[14:17]
    assert (bounds[31:34] == axis).all()
    for signs in np.array(np.meshgrid([1, -1], [1, -1], [1, -1])).T.reshape(-1, 3):
        v = signs * axis
        assert np.einsum("i,i->", v, v) <= TABLE.v_trans_max**2
    # ... and it is not vacuous: it passes 1.7 m/s along every axis at once.
    assert (axis >= 1.7).all()
