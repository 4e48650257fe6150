"""The joint generators' rules (fci/limits/joint.py): q_c and dq_c, one provocation and one
conforming twin per row.

Rows and precedence: docs/fci-behaviour.md "What is checked, and what it latches" and
"Which discontinuity you get depends on the interface". Numbers are the FR3 tables
(docs/limits.md §1, §4). Each provocation trips exactly the row it is named after (the
``check`` of its description says which row), and a conforming stream just inside the
same limit (0.99 x) trips nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.limits import NO_ERROR
from franka_sim_gym.fci.tables import FER, FR3
from tests.limit_rules_helpers import (
    DT,
    E11,
    E12,
    E13,
    E14,
    E15,
    HOME,
    TOL,
    Z,
    moving,
    on,
    position,
    velocity,
)

# NaN / inf inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")


# docs/limits.md §4, reference values of the FR3 envelope at HOME.
HOME_UPPER = (2.619, 2.619, 2.619, 2.619, 5.259, 4.179, 5.259)
HOME_LOWER = (-2.619, -2.0800, -2.619, -2.0517, -5.259, -3.0148, -5.259)


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
