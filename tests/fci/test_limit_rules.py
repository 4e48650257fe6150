"""The pure motion-limit rules: one provocation and one conforming twin per row.

Rows and precedence: docs/fci-behaviour.md "What is checked, and what it latches" and
"Which discontinuity you get depends on the interface"; the safety controller:
"joint_velocity_violation (3)" and "cartesian_velocity_violation (4)". Numbers
are the FR3 tables (docs/limits.md §1, §4). Each provocation trips exactly the row it
is named after (the ``check`` of its description says which row), and a
conforming stream just inside the same limit (0.99 x) trips nothing.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.limits import (
    MEASURED_VELOCITY_MARGIN,
    NO_ERROR,
    check_joint_position,
    check_joint_velocity,
    check_measured_cartesian_speed,
    check_measured_joint_velocity,
    check_torque,
    describe_joint_position,
    describe_joint_velocity,
    describe_measured_cartesian_speed,
    describe_measured_joint_velocity,
    describe_torque,
    safety_error,
)
from franka_sim_gym.fci.tables import FER, FR3

# NaN / inf inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")

DT = 1e-3
TOL = 0.1  # docs/fci-behaviour.md "Two deliberate departures": 0.1 rad and 0.1 rad/s (sim choices)
HOME = np.array([0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])
# docs/limits.md §4, reference values of the FR3 envelope at HOME.
HOME_UPPER = (2.619, 2.619, 2.619, 2.619, 5.259, 4.179, 5.259)
HOME_LOWER = (-2.619, -2.0800, -2.619, -2.0517, -5.259, -3.0148, -5.259)
Z = np.zeros(7)

E12 = Error.joint_motion_generator_position_limits_violation
E11 = Error.joint_position_motion_generator_start_pose_invalid
E13 = Error.joint_motion_generator_velocity_limits_violation
E14 = Error.joint_motion_generator_velocity_discontinuity
E15 = Error.joint_motion_generator_acceleration_discontinuity
E32 = Error.controller_torque_discontinuity
E34 = Error.tau_j_range_violation
E3 = Error.joint_velocity_violation
E4 = Error.cartesian_velocity_violation


def on(j: int, x: float, base=Z) -> np.ndarray:
    """``base`` with joint j (0-based) offset by x."""
    v = np.array(base, dtype=float)
    v[j] += x
    return v


def _b(x) -> np.ndarray:
    return np.asarray(x, dtype=float).reshape(1, -1)


def position(
    q_c, q_prev=HOME, dq_prev=Z, ddq_prev=Z, first=False, q_start=None, steps=1, table=FR3
):
    """One robot's check_joint_position; returns (error, describe, result)."""
    args = (
        _b(q_c),
        _b(q_prev),
        _b(dq_prev),
        _b(ddq_prev),
        np.array([first]),
        _b(q_prev if q_start is None else q_start),
        np.array([steps]),
        table,
        TOL,
    )
    result = check_joint_position(*args)
    return int(result.error[0]), describe_joint_position(0, *args), result


def velocity(
    dq_c, q_prev=HOME, dq_prev=Z, ddq_prev=Z, first=False, dq_start=None, steps=1, table=FR3
):
    """One robot's check_joint_velocity; returns (error, describe, result)."""
    args = (
        _b(dq_c),
        _b(q_prev),
        _b(dq_prev),
        _b(ddq_prev),
        np.array([first]),
        _b(dq_prev if dq_start is None else dq_start),
        np.array([steps]),
        table,
        TOL,
    )
    result = check_joint_velocity(*args)
    return int(result.error[0]), describe_joint_velocity(0, *args), result


def torque(tau_c, tau_prev=Z, first=False, steps=1):
    args = (_b(tau_c), _b(tau_prev), np.array([first]), np.array([steps]), FR3)
    return int(check_torque(*args)[0]), describe_torque(0, *args)


def moving(v: np.ndarray, steps: int = 1):
    """q_c from HOME for a stream whose new implied velocity is ``v`` (over ``steps``)."""
    return HOME + np.asarray(v) * steps * DT


# --- the tables these tests lean on ------------------------------------------------


def test_fr3_envelope_at_home_is_the_limits_md_reference():
    upper, lower = FR3.velocity_envelope(HOME)
    np.testing.assert_allclose(upper, HOME_UPPER, atol=1e-4)
    np.testing.assert_allclose(lower, HOME_LOWER, atol=1e-4)


# --- q_c: 12 range ---------------------------------------------------------------


@pytest.mark.parametrize("j", range(7))
def test_q_c_outside_the_joint_range_is_12(j):
    # First command (start pose matched, no derivative rows) isolates the range row.
    for out in (on(j, 1e-4, FR3.q_upper), on(j, -1e-4, FR3.q_lower)):
        out = np.where(np.arange(7) == j, out, HOME)
        error, why, _ = position(out, first=True, q_start=out)
        assert error == E12
        assert (why.check, why.joint) == ("range", j)
    inside = np.where(np.arange(7) == j, FR3.q_upper - 1e-4, HOME)
    assert position(inside, first=True, q_start=inside)[0] == NO_ERROR


def test_range_outranks_the_envelope_mid_motion():
    # Creeping across joint 1's upper stop at 1 mm/s: inside the last stretch the
    # envelope is already below zero (13), but the range row comes first.
    q_prev = HOME.copy()
    q_prev[0] = FR3.q_upper[0] - 0.5e-3
    v = on(0, 1.0)
    error, why, _ = position(q_prev + v * DT, q_prev=q_prev, dq_prev=v)
    assert (error, why.check) == (E12, "range")


# --- q_c: 11 start pose ------------------------------------------------------------


def test_first_q_c_away_from_q_d_is_11_start_pose():
    # The classic provocation (docs/fci-behaviour.md "Two deliberate departures"): +0.2 rad on joint
    # 1 on the opening command.
    error, why, _ = position(on(0, 0.2, HOME), first=True)
    assert error == E11
    assert (why.check, why.joint, why.limit) == ("start pose", 0, TOL)
    assert why.value == pytest.approx(0.2)
    assert position(on(6, -0.2, HOME), first=True)[0] == E11
    # 0.99 x the tolerance, either sign: no error, and no derivative row either.
    assert position(on(0, 0.99 * TOL, HOME), first=True)[0] == NO_ERROR
    assert position(on(3, -0.99 * TOL, HOME), first=True)[0] == NO_ERROR


def test_start_pose_outranks_discontinuity_but_not_range():
    jump = on(0, 0.2, HOME)
    assert position(jump, first=True)[0] == E11  # 200 rad/s implied: still 11
    assert position(jump, first=False)[0] == E14  # the same step mid-motion
    # Out of range *and* away from q_d: 12 (docs/fci-behaviour.md "Which discontinuity you get
    # depends on the interface": our ordering).
    q_start = on(0, 0.0, HOME)
    q_start[0] = 2.70
    q_c = q_start.copy()
    q_c[0] = 2.85
    assert position(q_c, first=True, q_start=q_start)[0] == E12


def test_first_command_is_at_rest_and_skips_the_derivative_rows():
    # The history says 2 rad/s and 50 rad/s^2 (stale); the opening command is
    # judged on its start pose only, and the derivatives to record are zero.
    error, why, result = position(
        on(0, 0.05, HOME), dq_prev=on(0, 2.0), ddq_prev=on(1, 50.0), first=True
    )
    assert error == NO_ERROR and why is None
    assert not result.dq.any() and not result.ddq.any()


def test_start_pose_applies_only_to_the_first_command():
    # The same 0.2 rad deviation from q_start, mid-motion at a conforming pace.
    q_start = on(0, -0.2, HOME)
    assert position(HOME, q_start=q_start)[0] == NO_ERROR


# --- q_c: 14 / 13 / 15 -----------------------------------------------------------


def test_one_rad_step_is_14_not_13():
    error, why, _ = position(on(0, 1.0, HOME))
    assert error == E14  # 1000 rad/s breaks the envelope too, and the jerk
    assert (why.check, why.joint, why.unit) == ("acceleration", 0, "rad/s^2")
    assert why.value == pytest.approx(1e6)
    assert why.limit == pytest.approx(9.999)
    assert "joint 1 = 1e+06 rad/s^2, limit 9.999 rad/s^2" in why.message()


def test_implied_acceleration_is_14_velocity_discontinuity():
    # Constant acceleration 10.5 rad/s^2 (zero jerk, low speed).
    for j in range(7):
        v0, a = on(j, 0.5), on(j, 10.5)
        error, why, _ = position(moving(v0 + a * DT), dq_prev=v0, ddq_prev=a)
        assert (error, why.check, why.joint) == (E14, "acceleration", j)
    a = on(2, -0.99 * FR3.ddq_max[2])
    assert position(moving(a * DT), ddq_prev=a)[0] == NO_ERROR


def test_smoothly_too_fast_is_13():
    # Constant velocity, zero acceleration: FR3 joint 1 above 2.619 rad/s at HOME.
    v = on(0, 2.65)
    error, why, _ = position(moving(v), dq_prev=v)
    assert (error, why.check, why.joint) == (E13, "velocity", 0)
    assert why.limit == pytest.approx(2.619)
    v = on(0, 0.99 * 2.619)
    assert position(moving(v), dq_prev=v)[0] == NO_ERROR


def test_smoothly_too_fast_on_the_lower_envelope_is_13():
    # Joint 2 at -pi/4: the lower envelope is -2.0800, not -2.62 (docs/limits.md §4).
    v = on(1, -2.10)
    error, why, _ = position(moving(v), dq_prev=v)
    assert (error, why.joint) == (E13, 1)
    assert why.limit == pytest.approx(-2.0800, abs=1e-4)
    v = on(1, 0.99 * -2.0800)
    assert position(moving(v), dq_prev=v)[0] == NO_ERROR


def test_envelope_is_evaluated_at_the_previous_reference():
    # Joint 4, 0.05 rad below its upper stop: the envelope there is
    # -0.30 + sqrt(2 * 4.0 * 0.05) - 1e-3 = 0.33146 rad/s, far under dq_max.
    q_prev = HOME.copy()
    q_prev[3] = FR3.q_upper[3] - 0.05
    limit = -0.30 + math.sqrt(2 * 4.0 * 0.05) - 1e-3
    for v, expected in ((0.34, E13), (0.99 * limit, NO_ERROR)):
        dq = on(3, v)
        assert position(q_prev + dq * DT, q_prev=q_prev, dq_prev=dq)[0] == expected


def test_jerk_is_15():
    # From rest, acceleration 6 rad/s^2 in one cycle: jerk 6000 > 4999.999.
    for j in range(7):
        a = on(j, 6.0)
        error, why, _ = position(moving(a * DT))
        assert (error, why.check, why.joint) == (E15, "jerk", j)
        assert why.limit == pytest.approx(4999.999)
    a = on(4, -0.99 * 4999.999 * DT)
    assert position(moving(a * DT))[0] == NO_ERROR


def test_discontinuity_outranks_envelope_outranks_jerk():
    # 14 and 13 at once: 14.
    v0, a = on(0, 2.61), on(0, 20.0)
    assert position(moving(v0 + a * DT), dq_prev=v0, ddq_prev=a)[0] == E14
    # 13 and 15 at once: 13 (docs/motion-limits.md lists the envelope before the jerk).
    v0 = on(0, 2.65)
    assert position(moving(v0 + on(0, 6.0) * DT), dq_prev=v0)[0] == E13


def test_derivatives_over_steps_3_divide_by_three_cycles():
    # 1 rad/s, constant: 3 mm of travel over 3 published cycles is conforming...
    v = on(0, 1.0)
    error, _, result = position(moving(v, steps=3), dq_prev=v, steps=3)
    assert error == NO_ERROR
    np.testing.assert_allclose(result.dq[0], v, rtol=1e-9)
    np.testing.assert_allclose(result.ddq[0], Z, atol=1e-6)
    # ... while over an assumed millisecond it would be a 3 rad/s jump.
    assert position(moving(v, steps=3), dq_prev=v, steps=1)[0] == E14
    # Constant 10.5 rad/s^2 over 3 cycles is still 14; 0.99 x the limit is not.
    for a, expected in ((10.5, E14), (0.99 * 9.999, NO_ERROR)):
        dq = on(0, a * 3 * DT)
        q_c = moving(dq, steps=3)
        error, _, result = position(q_c, ddq_prev=on(0, a), steps=3)
        assert error == expected
        assert result.ddq[0, 0] == pytest.approx(a, rel=1e-6)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("first", [False, True])
def test_non_finite_q_c_is_12(bad, first):
    q_c = on(4, 0.0, HOME)
    q_c[4] = bad
    error, why, _ = position(q_c, first=first)
    assert error == E12
    assert (why.check, why.joint) == ("non-finite", 4)
    assert math.isnan(why.limit)


# --- dq_c: 15 / 13 ---------------------------------------------------------------


def test_velocity_interface_names_shift_by_one():
    # The same 10.5 rad/s^2 acceleration: 14 on q_c, 15 on dq_c.
    v0, a = on(0, 0.5), on(0, 10.5)
    assert position(moving(v0 + a * DT), dq_prev=v0, ddq_prev=a)[0] == E14
    error, why, _ = velocity(v0 + a * DT, dq_prev=v0, ddq_prev=a)
    assert (error, why.check) == (E15, "acceleration")
    # A jerk is 15 on both.
    error, why, _ = velocity(on(5, 6.0 * DT))
    assert (error, why.check, why.joint) == (E15, "jerk", 5)
    # 0.99 x either limit: nothing.
    a = on(0, 0.99 * 9.999)
    assert velocity(v0 + a * DT, dq_prev=v0, ddq_prev=a)[0] == NO_ERROR
    assert velocity(on(5, 0.99 * 4999.999 * DT * DT))[0] == NO_ERROR


def test_50_rad_per_s_step_in_dq_c_is_15_not_13_or_14():
    error, why, _ = velocity(on(0, 50.0))
    assert error == E15
    assert why.check == "acceleration"


def test_first_dq_c_away_from_dq_d_is_15():
    error, why, _ = velocity(on(0, 0.2), first=True, dq_start=Z)
    assert (error, why.check, why.joint, why.limit) == (E15, "start velocity", 0, TOL)
    # 0.099 rad/s would be a 99 rad/s^2 step; on the opening command it is the
    # start check alone that judges it.
    error, _, result = velocity(on(0, 0.99 * TOL), first=True, dq_start=Z)
    assert error == NO_ERROR
    assert not result.ddq.any()


def test_dq_c_outside_the_envelope_is_13():
    for v, j in ((2.65, 0), (-2.10, 1)):
        dq = on(j, v)
        error, why, _ = velocity(dq, dq_prev=dq)
        assert (error, why.check, why.joint) == (E13, "velocity", j)
    for v, j in ((0.99 * 2.619, 0), (0.99 * -2.0800, 1)):
        dq = on(j, v)
        assert velocity(dq, dq_prev=dq)[0] == NO_ERROR
    # The envelope still applies to the opening command.
    dq = on(0, 2.65)
    assert velocity(dq, first=True, dq_start=dq)[0] == E13


def test_commanding_into_a_stop_is_13_on_the_velocity_interface():
    # No range row on dq_c: 1 mrad from joint 4's upper stop, inward motion is 13.
    q_prev = HOME.copy()
    q_prev[3] = FR3.q_upper[3] - 1e-3
    dq = on(3, 0.01)
    error, why, _ = velocity(dq, q_prev=q_prev, dq_prev=dq)
    assert (error, why.joint, why.limit) == (E13, 3, pytest.approx(-1e-3))
    away = on(3, -0.01)
    assert velocity(away, q_prev=q_prev, dq_prev=away)[0] == NO_ERROR


def test_dq_c_discontinuity_outranks_the_envelope():
    v0 = on(0, 2.65)  # already outside the envelope, then a jerk on top
    assert velocity(v0 + on(0, 6.0) * DT, dq_prev=v0)[0] == E15


def test_dq_c_over_steps_3():
    # 9 rad/s^2 over 3 cycles: conforming; the same change over one cycle is 27.
    dq = on(0, 9.0 * 3 * DT)
    error, _, result = velocity(dq, ddq_prev=on(0, 9.0), steps=3)
    assert error == NO_ERROR
    assert result.ddq[0, 0] == pytest.approx(9.0)
    assert velocity(dq, ddq_prev=on(0, 9.0), steps=1)[0] == E15


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("first", [False, True])
def test_non_finite_dq_c_is_13(bad, first):
    dq = on(2, 0.0)
    dq[2] = bad
    error, why, _ = velocity(dq, first=first, dq_start=on(0, 1.0))
    assert error == E13
    assert (why.check, why.joint) == ("non-finite", 2)


def test_fer_envelope_is_constant():
    # FCI v5 / FER: no position dependence, 2.175 - 1e-3 everywhere.
    q = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0])
    for v, expected in ((2.18, E13), (0.99 * 2.174, NO_ERROR)):
        dq = on(0, v)
        assert velocity(dq, q_prev=q, dq_prev=dq, table=FER)[0] == expected


# --- tau_J_d: 34 / 32 ------------------------------------------------------------


def test_torque_step_is_32():
    # A torque motion starts from tau_d = 0: a 1 Nm opening step is 1000 Nm/s.
    for first in (True, False):
        error, why = torque(on(0, 1.0), first=first)
        assert (error, why.check, why.joint, why.unit) == (E32, "rate", 0, "Nm/s")
        assert why.limit == pytest.approx(999.999)
    assert torque(on(0, 0.99 * 999.999 * DT), first=True)[0] == NO_ERROR


@pytest.mark.parametrize("j", range(7))
def test_torque_outside_the_effort_limit_is_34(j):
    limit = FR3.tau_max[j]  # 87 / 12 Nm
    prev = on(j, -limit)
    error, why = torque(on(j, -limit - 5e-4), tau_prev=prev)  # 0.5 Nm/s: no rate issue
    assert (error, why.check, why.joint, why.limit) == (E34, "range", j, limit)
    held = on(j, 0.99 * limit)
    assert torque(held, tau_prev=held)[0] == NO_ERROR


def test_torque_range_outranks_rate():
    assert torque(on(0, 100.0))[0] == E34


def test_torque_rate_over_steps():
    assert torque(on(0, 2.0), steps=3)[0] == NO_ERROR  # 667 Nm/s
    assert torque(on(0, 2.0), steps=1)[0] == E32


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_torque_is_34(bad):
    tau = on(6, 0.0)
    tau[6] = bad
    error, why = torque(tau)
    assert (error, why.check, why.joint) == (E34, "non-finite", 6)


# --- safety controller: 3 / 4 ----------------------------------------------------


def _measured_joint(dq, q=HOME, margin=MEASURED_VELOCITY_MARGIN):
    error = int(check_measured_joint_velocity(_b(dq), _b(q), FR3, margin)[0])
    return error, describe_measured_joint_velocity(0, _b(dq), _b(q), FR3, margin)


def _measured_speed(v):
    error = int(check_measured_cartesian_speed(_b(v), FR3)[0])
    return error, describe_measured_cartesian_speed(0, _b(v), FR3)


def test_measured_joint_velocity_beyond_envelope_plus_margin_is_3():
    error, why = _measured_joint(on(0, 2.619 + 0.1 + 0.01))
    assert (error, why.joint, why.signal) == (E3, 0, "dq")
    assert why.limit == pytest.approx(2.719)
    assert _measured_joint(on(1, -2.0800 - 0.11))[0] == E3
    # Inside the margin, and 0.99 x the envelope: nothing.
    assert _measured_joint(on(0, 2.619 + 0.09))[0] == NO_ERROR
    assert _measured_joint(on(1, 0.99 * -2.0800))[0] == NO_ERROR
    # The margin is an argument: with none, the envelope itself.
    assert _measured_joint(on(0, 2.62), margin=0.0)[0] == E3


def test_measured_cartesian_speed_above_3_m_per_s_is_4():
    for v in ((3.0, 0.0, 0.0), (2.0, 2.0, 1.0), (0.0, 0.0, -2.999 - 1e-6)):
        error, why = _measured_speed(v)
        assert (error, why.joint) == (E4, -1)
        assert why.limit == pytest.approx(2.999)
    assert _measured_speed((0.99 * 2.999, 0.0, 0.0))[0] == NO_ERROR
    assert _measured_speed((1.7, 1.7, 1.0))[0] == NO_ERROR  # 2.6 m/s


def test_measured_cartesian_speed_outranks_joint_velocity():
    joint = np.array([E3, E3, NO_ERROR, NO_ERROR])
    cartesian = np.array([E4, NO_ERROR, E4, NO_ERROR])
    assert safety_error(joint, cartesian).tolist() == [E4, E3, E4, NO_ERROR]


def test_non_finite_measured_velocity_is_a_violation():
    assert _measured_joint(on(0, math.nan))[0] == E3
    assert _measured_speed((math.nan, 0.0, 0.0))[0] == E4


# --- batches ---------------------------------------------------------------------


def test_robots_in_one_call_get_independent_results():
    # Six robots, one scenario each, in one call; then each alone.
    out_of_range = HOME.copy()
    out_of_range[0] = FR3.q_upper[0] + 1e-4
    v0, a, v_fast = on(0, 0.5), on(0, 10.5), on(0, 2.65)
    rows = [  # q_c, q_prev, dq_prev, ddq_prev, first, steps, expected
        (out_of_range, HOME, Z, Z, True, 1, E12),
        (on(0, 0.2, HOME), HOME, Z, Z, True, 1, E11),
        (moving(v0 + a * DT), HOME, v0, a, False, 1, E14),
        (moving(v_fast), HOME, v_fast, Z, False, 1, E13),
        (moving(on(0, 6.0) * DT), HOME, Z, Z, False, 1, E15),
        (moving(on(0, 1.0), steps=3), HOME, on(0, 1.0), Z, False, 3, NO_ERROR),
    ]
    q_c, q_prev, dq_prev, ddq_prev = (np.stack([r[k] for r in rows]) for k in range(4))
    first = np.array([r[4] for r in rows])
    steps = np.array([r[5] for r in rows])
    q_start = q_prev.copy()
    q_start[0] = q_c[0]
    result = check_joint_position(q_c, q_prev, dq_prev, ddq_prev, first, q_start, steps, FR3, TOL)
    assert result.error.dtype == np.int64 and result.error.shape == (6,)
    assert result.error.tolist() == [r[6] for r in rows]
    for i in range(6):
        alone = check_joint_position(
            q_c[i : i + 1],
            q_prev[i : i + 1],
            dq_prev[i : i + 1],
            ddq_prev[i : i + 1],
            first[i : i + 1],
            q_start[i : i + 1],
            steps[i : i + 1],
            FR3,
            TOL,
        )
        assert alone.error[0] == result.error[i]
        np.testing.assert_array_equal(alone.dq[0], result.dq[i])
    assert not result.dq[:2].any()  # the two opening commands rest


def _oracle_position(q_c, q_prev, dq_prev, ddq_prev, first, q_start, steps):
    """The q_c table of docs/motion-limits.md read row by row, one robot, plain Python control
    flow."""
    h = steps * DT
    dq = (q_c - q_prev) / h
    ddq = (dq - dq_prev) / h
    dddq = (ddq - ddq_prev) / h
    upper, lower = FR3.velocity_envelope(q_prev)
    if not all(FR3.q_lower[j] <= q_c[j] <= FR3.q_upper[j] for j in range(7)):
        return E12
    if first:
        return E11 if any(abs(q_c[j] - q_start[j]) > TOL for j in range(7)) else NO_ERROR
    if any(abs(ddq[j]) > FR3.ddq_max[j] for j in range(7)):
        return E14
    if any(dq[j] > upper[j] or dq[j] < lower[j] for j in range(7)):
        return E13
    if any(abs(dddq[j]) > FR3.dddq_max[j] for j in range(7)):
        return E15
    return NO_ERROR


def _oracle_velocity(dq_c, q_prev, dq_prev, ddq_prev, first, dq_start, steps):
    if not np.isfinite(dq_c).all():
        return E13
    h = steps * DT
    ddq = (dq_c - dq_prev) / h
    dddq = (ddq - ddq_prev) / h
    upper, lower = FR3.velocity_envelope(q_prev)
    if first and any(abs(dq_c[j] - dq_start[j]) > TOL for j in range(7)):
        return E15
    if not first and any(abs(ddq[j]) > FR3.ddq_max[j] for j in range(7)):
        return E15
    if not first and any(abs(dddq[j]) > FR3.dddq_max[j] for j in range(7)):
        return E15
    if any(dq_c[j] > upper[j] or dq_c[j] < lower[j] for j in range(7)):
        return E13
    return NO_ERROR


def _random_batch(seed: int, n: int):
    """n robots mid-stream near every boundary: positions anywhere in the range
    (stops included), velocities around the envelope, accelerations and jerks
    around their limits, plus the odd jump, opening command and NaN."""
    rng = np.random.default_rng(seed)
    span = FR3.q_upper - FR3.q_lower
    q_prev = FR3.q_lower + span * rng.choice([0.0, 1e-3, 0.02, 0.5, 0.98, 0.999, 1.0], (n, 7))
    q_prev += rng.normal(scale=1e-3, size=(n, 7))
    upper, lower = FR3.velocity_envelope(q_prev)
    dq_prev = rng.uniform(1.05 * lower, 1.05 * upper) * (rng.random((n, 1)) < 0.8)
    ddq_prev = rng.uniform(-11.0, 11.0, (n, 7)) * (rng.random((n, 1)) < 0.8)
    steps = rng.integers(1, 4, n)
    h = steps[:, None] * DT
    jerk = rng.uniform(-5500.0, 5500.0, (n, 7)) * (rng.random((n, 7)) < 0.3)
    ddq = ddq_prev + jerk * h
    dq = dq_prev + ddq * h
    jump = rng.choice([0.0, 0.0, 0.0, 0.0, 0.05, 0.2, 1.0], (n, 1)) * rng.normal(size=(n, 7))
    q_c = q_prev + dq * h + jump * (rng.random((n, 7)) < 0.2)
    dq_c = dq + 10.0 * jump * (rng.random((n, 7)) < 0.2)
    nan = rng.random((n, 7)) < 0.01
    q_c[nan], dq_c[nan] = np.nan, np.inf
    first = rng.random(n) < 0.2
    start = q_c + rng.choice([0.0, 0.05, 0.3], (n, 1)) * rng.normal(size=(n, 7))
    return q_c, dq_c, q_prev, dq_prev, ddq_prev, first, start, steps


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 8))
def test_batch_matches_the_row_by_row_reading_of_the_seed(seed, n):
    q_c, dq_c, q_prev, dq_prev, ddq_prev, first, start, steps = _random_batch(seed, n)
    got = check_joint_position(q_c, q_prev, dq_prev, ddq_prev, first, start, steps, FR3, TOL)
    want = [
        _oracle_position(q_c[i], q_prev[i], dq_prev[i], ddq_prev[i], first[i], start[i], steps[i])
        for i in range(n)
    ]
    assert got.error.tolist() == want
    start = start - q_c + dq_c
    got = check_joint_velocity(dq_c, q_prev, dq_prev, ddq_prev, first, start, steps, FR3, TOL)
    want = [
        _oracle_velocity(dq_c[i], q_prev[i], dq_prev[i], ddq_prev[i], first[i], start[i], steps[i])
        for i in range(n)
    ]
    assert got.error.tolist() == want
    for i in np.flatnonzero(got.error != NO_ERROR):
        why = describe_joint_velocity(
            i, dq_c, q_prev, dq_prev, ddq_prev, first, start, steps, FR3, TOL
        )
        assert why is not None and why.error == got.error[i]


def test_scalar_first_and_steps_broadcast():
    q_c = np.stack([HOME, on(0, 1.0, HOME)])
    q_prev = np.stack([HOME, HOME])
    result = check_joint_position(q_c, q_prev, q_prev * 0, q_prev * 0, False, q_prev, 1, FR3, TOL)
    assert result.error.tolist() == [NO_ERROR, E14]


# --- cost ------------------------------------------------------------------------


def _per_call(fn, repeat: int = 2000) -> float:
    fn()
    start = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - start) / repeat


def test_one_call_per_cycle_is_a_handful_of_numpy_ops():
    """Not a speed assertion: the n=1 cost is printed, and n=256 must not cost
    256 x as much (no Python loop over robots or joints on the clean path)."""

    def call(n):
        q = np.tile(HOME, (n, 1))
        zero = np.zeros((n, 7))
        first = np.zeros(n, dtype=bool)
        steps = np.ones(n, dtype=np.int64)
        return lambda: check_joint_position(q, q, zero, zero, first, q, steps, FR3, TOL)

    one, many = _per_call(call(1)), _per_call(call(256), repeat=500)
    print(f"check_joint_position: n=1 {one * 1e6:.1f} us, n=256 {many * 1e6:.1f} us")
    assert one < 1e-3
    assert many < 20 * one
