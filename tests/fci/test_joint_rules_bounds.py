"""The joint rules at their bounds (fci/limits/_joint.c position_rule / velocity_rule):
a value on a bound is inside, one representable step past it trips the row, and the log
line names the bound crossed.

docs/fci-behaviour.md "What is checked, and what it latches": every row is an inequality,
"<=" the limit (the tables' constants are already "limit - 1e-3"); the derivatives are the
backward differences of "The difference formulas" over one cycle. Each case builds the
command whose difference lands exactly on the bound (walking float by float from a first
guess), so a ">=" for ">" in the C text, or a bound read as exclusive, turns it red.
"""

from __future__ import annotations

import numpy as np
import pytest

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
    on,
    position,
    velocity,
)

#: Joints 1 and 2 (FR3: acceleration limits 15 and 7.5 rad/s^2, jerk 7,500 and 3,750 rad/s^3,
#: so a rule reading another joint's limit fails), each from a reference with it at 0.0:
#: a difference from the reference on it is then the command itself.
JOINTS = (0, 1)


#: The derivative rows on joints whose limits differ: FR3's acceleration and jerk limits are
#: the same on every joint, the FER's are not (joint 2: 7.5 rad/s^2 against joint 1's 15).
DERIVATIVE_CASES = [(FR3, 0), (FER, 1)]


def base(j: int) -> np.ndarray:
    """HOME with joint j at 0.0 (inside both joints' ranges)."""
    return on(j, -HOME[j], HOME)


def on_and_past(f, guess: float, bound: float, sign: float = 1.0) -> tuple[float, float]:
    """(x, past): x with f(x) == bound exactly, past the float next to it away from the
    inside, the first where f is beyond the bound (``sign`` -1: a lower bound)."""
    away = np.inf * sign
    x = float(guess)
    for _ in range(64):  # a few floats from the guess (f increasing, away from the inside)
        if sign * f(x) <= sign * bound:
            break
        x = float(np.nextafter(x, -away))
    for _ in range(64):
        if sign * f(float(np.nextafter(x, away))) > sign * bound:
            break
        x = float(np.nextafter(x, away))
    assert f(x) == bound, "no float lands exactly on the bound from this guess"
    past = float(np.nextafter(x, away))
    assert sign * f(past) > sign * bound
    return x, past


def envelope_at(q: np.ndarray, j: int) -> tuple[float, float]:
    """Joint j's (upper, lower) velocity envelope at q (RobotTable.velocity_envelope)."""
    upper, lower = FR3.velocity_envelope(q.reshape(1, 7))
    return float(upper[0, j]), float(lower[0, j])


@pytest.mark.parametrize("J", JOINTS)
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_q_c_on_the_joint_range_bound_is_inside_and_one_float_past_is_12(side, J):
    bound = float(getattr(FR3, f"q_{side}")[J])
    away = np.inf if side == "upper" else -np.inf
    on_bound = on(J, bound, base(J))
    assert position(on_bound, first=True, q_start=on_bound)[0] == -1
    beyond = on_bound.copy()
    beyond[J] = np.nextafter(bound, away)
    error, why, _ = position(beyond, first=True, q_start=beyond)
    assert error == E12
    assert why.joint == J and why.limit == bound and why.check == "range"


@pytest.mark.parametrize("J", JOINTS)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_start_pose_on_its_tolerance_is_inside_and_one_float_past_is_11(sign, J):
    """|q_c - q_start| <= 0.1 rad (docs/fci-behaviour.md "Two deliberate departures"); the
    log line gives the tolerance as the bound's magnitude, either side."""
    ref = base(J)
    assert position(on(J, sign * TOL, ref), ref, first=True)[0] == -1
    error, why, _ = position(
        on(J, float(np.nextafter(sign * TOL, sign * np.inf)), ref), ref, first=True
    )
    assert error == E11
    assert why.joint == J and why.limit == TOL and why.check == "start pose"


@pytest.mark.parametrize(("table", "J"), DERIVATIVE_CASES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_q_c_acceleration_on_its_limit_is_inside_and_one_float_past_is_14(sign, table, J):
    a_max = float(table.ddq_max[J])
    # dq = q_c / dt from rest at HOME, ddq = dq / dt; ddq_prev = ddq keeps the jerk at 0
    x, past = on_and_past(lambda q: (q / DT) / DT, sign * a_max * DT * DT, sign * a_max, sign)
    history = dict(q_prev=base(J), ddq_prev=on(J, sign * a_max))
    assert position(on(J, x, base(J)), **history, table=table)[0] == -1
    error, why, _ = position(on(J, past, base(J)), **history, table=table)
    assert error == E14
    assert why.joint == J and why.limit == a_max and why.check == "acceleration"


@pytest.mark.parametrize("J", JOINTS)
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_q_c_velocity_on_the_envelope_is_inside_and_one_float_past_is_13(side, J):
    upper, lower = envelope_at(base(J), J)
    bound, sign = (upper, 1.0) if side == "upper" else (lower, -1.0)
    x, past = on_and_past(lambda q: q / DT, bound * DT, bound, sign)
    # dq_prev = dq keeps the acceleration (and the jerk) at 0
    history = dict(q_prev=base(J), dq_prev=on(J, bound))
    assert position(on(J, x, base(J)), **history)[0] == -1
    error, why, _ = position(on(J, past, base(J)), **history)
    assert error == E13
    assert why.joint == J and why.limit == bound and why.check == "velocity"


@pytest.mark.parametrize(("table", "J"), DERIVATIVE_CASES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_q_c_jerk_on_its_limit_is_inside_and_one_float_past_is_15(sign, table, J):
    j_max = float(table.dddq_max[J])
    # q_c = q_prev, dq_prev = 0: dq = ddq = 0, so dddq = (0 - ddq_prev) / dt = b / dt for
    # ddq_prev = -b (the negation and the subtraction from 0 are exact)
    x, past = on_and_past(lambda b: b / DT, sign * j_max * DT, sign * j_max, sign)
    at, beyond = (dict(q_prev=base(J), ddq_prev=on(J, -b)) for b in (x, past))
    assert position(base(J), **at, table=table)[0] == -1
    error, why, _ = position(base(J), **beyond, table=table)
    assert error == E15
    assert why.joint == J and why.limit == j_max and why.check == "jerk"


@pytest.mark.parametrize("J", JOINTS)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_start_velocity_on_its_tolerance_is_inside_and_one_float_past_is_15(sign, J):
    assert velocity(on(J, sign * TOL), first=True, dq_start=Z)[0] == -1
    error, why, _ = velocity(
        on(J, float(np.nextafter(sign * TOL, sign * np.inf))), first=True, dq_start=Z
    )
    assert error == E15
    assert why.joint == J and why.limit == TOL and why.check == "start velocity"


@pytest.mark.parametrize(("table", "J"), DERIVATIVE_CASES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_dq_c_acceleration_on_its_limit_is_inside_and_one_float_past_is_15(sign, table, J):
    a_max = float(table.ddq_max[J])
    x, past = on_and_past(lambda v: v / DT, sign * a_max * DT, sign * a_max, sign)
    history = dict(ddq_prev=on(J, sign * a_max))
    assert velocity(on(J, x), **history, table=table)[0] == -1
    error, why, _ = velocity(on(J, past), **history, table=table)
    assert error == E15
    assert why.joint == J and why.limit == a_max and why.check == "acceleration"


@pytest.mark.parametrize(("table", "J"), DERIVATIVE_CASES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_dq_c_jerk_on_its_limit_is_inside_and_one_float_past_is_15(sign, table, J):
    j_max = float(table.dddq_max[J])
    x, past = on_and_past(lambda b: b / DT, sign * j_max * DT, sign * j_max, sign)
    at, beyond = (dict(ddq_prev=on(J, -b)) for b in (x, past))
    assert velocity(Z, **at, table=table)[0] == -1
    error, why, _ = velocity(Z, **beyond, table=table)
    assert error == E15
    assert why.joint == J and why.limit == j_max and why.check == "jerk"


@pytest.mark.parametrize("J", JOINTS)
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_dq_c_on_the_envelope_is_inside_and_one_float_past_is_13(side, J):
    upper, lower = envelope_at(base(J), J)
    bound = upper if side == "upper" else lower
    past = float(np.nextafter(bound, np.inf if side == "upper" else -np.inf))
    assert velocity(on(J, bound), base(J), dq_prev=on(J, bound))[0] == -1
    error, why, _ = velocity(on(J, past), base(J), dq_prev=on(J, past))
    assert error == E13
    assert why.joint == J and why.limit == bound and why.check == "velocity"


def test_of_joints_equally_far_outside_the_log_line_names_the_first():
    q_c = HOME.copy()
    q_c[[0, 2]] = 0.2  # 0.2 rad from a start of 0 on joints 1 and 3, inside their ranges
    error, why, _ = position(q_c, first=True, q_start=q_c * [0, 1, 0, 1, 1, 1, 1])
    assert error == E11
    assert why.joint == 0 and why.value == 0.2
    dq_c = on(2, 0.2, on(0, 0.2))
    error, why, _ = velocity(dq_c, first=True, dq_start=Z)
    assert error == E15 and why.joint == 0


def test_a_joint_whose_envelope_is_nan_is_named_before_one_outside_it():
    """docs/fci-behaviour.md: a non-finite reference is not "inside"; among the joints
    outside the dq_c envelope the log line names the one without a distance to its bound
    (its envelope at a NaN q_d) first, as numpy's argmax of the excess did."""
    q_prev = on(3, np.nan, HOME)
    dq_c = on(0, 5.0)  # joint 1 far outside its envelope (about 2.6 rad/s)
    error, why, _ = velocity(dq_c, q_prev, dq_prev=dq_c)
    assert error == E13
    assert why.joint == 3 and why.check == "velocity" and np.isnan(why.limit)
