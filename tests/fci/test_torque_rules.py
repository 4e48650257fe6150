"""The torque rules (fci/limits/torque.py, whose only text is C): tau_J_d's range (34)
and rate (32), one provocation and one conforming twin per row, the bounds themselves,
each robot on its own rows (docs/fci-behaviour.md "What is checked, and what it
latches")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.limits import NO_ERROR, check_torque, describe_torque
from franka_sim_gym.fci.tables import FR3
from tests.limit_rules_helpers import DT, E32, E34, Z, as_batch, on

# NaN / inf inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")


def torque(tau_c, tau_prev=Z, first=False, steps=1):
    steps = steps if isinstance(steps, np.ndarray) else np.array([steps])
    args = (as_batch(tau_c), as_batch(tau_prev), np.array([first]), steps, FR3)
    return int(check_torque(*args)[0]), describe_torque(0, *args)


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


def test_the_bounds_themselves_pass_and_one_ulp_beyond_trips():
    for j in (0, 4):
        limit = FR3.tau_max[j]
        for bound, beyond in ((limit, math.inf), (-limit, -math.inf)):
            assert torque(on(j, bound), tau_prev=on(j, bound))[0] == NO_ERROR
            past = math.nextafter(bound, beyond)
            assert torque(on(j, past), tau_prev=on(j, past))[0] == E34
    # the rate: a step of 999.999 Nm/s x 1 ms, exactly, computed as the rule does
    step = FR3.dtau_max * DT
    assert abs(step) / DT == FR3.dtau_max  # the step reads back as the limit itself
    assert torque(on(2, step))[0] == NO_ERROR
    assert torque(on(2, math.nextafter(step, 1.0)))[0] == E32


def test_each_robot_is_judged_on_its_own_interval_and_described_on_its_own_rows():
    tau = np.zeros((3, 7))
    tau[:, 1] = 2.0  # 2 Nm a step: 2000 Nm/s over one cycle, 667 over three
    tau[2, 5] = 13.0  # robot 2: joint 6 beyond 12 Nm
    prev, first = np.zeros((3, 7)), np.zeros(3, bool)
    steps = np.array([1, 3, 3])
    args = (tau, prev, first, steps, FR3)
    assert check_torque(*args).tolist() == [E32, NO_ERROR, E34]
    assert check_torque(tau, prev, first, 3, FR3).tolist() == [NO_ERROR, NO_ERROR, E34]
    strided = np.array([1, 1, 3, 1, 3, 1])[::2]  # [1, 3, 3], every other int64
    assert check_torque(tau, prev, first, strided, FR3).tolist() == [E32, NO_ERROR, E34]
    rate = describe_torque(np.int64(0), *args)  # a numpy index, as np.flatnonzero gives
    assert (rate.check, rate.joint, rate.value) == ("rate", 1, pytest.approx(2000.0))
    assert describe_torque(1, *args) is None
    assert (describe_torque(2, *args).joint, describe_torque(2, *args).value) == (5, 13.0)
    with pytest.raises(IndexError, match="robot 3 of 3"):
        describe_torque(3, *args)


def test_the_worst_joint_is_named_with_its_limit():
    error, why = torque(on(1, 88.0) + on(5, 14.0))  # 1 Nm beyond 87, 2 Nm beyond 12
    assert (error, why.joint, why.limit, why.check) == (E34, 5, 12.0, "range")
    assert why.message() == "tau_J_range_violation: tau_J_d joint 6 = 14 Nm, limit 12 Nm (range)"


def test_steps_that_are_not_integers_are_refused():
    args = (as_batch(Z), as_batch(Z), np.array([False]))
    with pytest.raises(ValueError, match="steps: expected one integer or"):
        check_torque(*args, np.array([1.0]), FR3)
    with pytest.raises(ValueError, match=r"steps: expected one integer or \(1,\) integers"):
        check_torque(*args, np.array([1, 1]), FR3)


def test_a_non_finite_torque_is_named_before_a_finite_one_further_out():
    error, why = torque(on(1, 100.0) + on(6, math.nan))
    assert (error, why.check, why.joint) == (E34, "non-finite", 6)


def test_a_falling_torque_trips_the_rate_on_every_joint():
    for j in range(7):
        held = on(j, 5.0)
        error, why = torque(held - on(j, 2.0), tau_prev=held)  # -2 Nm in a cycle
        assert (error, why.joint, why.value) == (E32, j, pytest.approx(-2000.0))
        assert torque(held - on(j, 0.99 * 999.999 * DT), tau_prev=held)[0] == NO_ERROR


def test_each_robot_rates_against_its_own_previous_torque():
    prev = np.zeros((2, 7))
    prev[1, 3] = 1.5  # robot 1 held 1.5 Nm on joint 4
    tau = np.tile(on(3, 1.5), (2, 1))
    assert check_torque(tau, prev, np.zeros(2, bool), 1, FR3).tolist() == [E32, NO_ERROR]


def test_the_log_line_keeps_the_sign_and_an_infinite_torque_has_no_bound():
    error, why = torque(on(4, -13.0))
    assert (why.value, why.limit) == (-13.0, 12.0)
    assert why.message() == "tau_J_range_violation: tau_J_d joint 5 = -13 Nm, limit 12 Nm (range)"
    error, why = torque(on(2, -math.inf))
    assert (why.check, why.value) == ("non-finite", -math.inf) and math.isnan(why.limit)
    # equal excess on two joints: the first is named
    assert torque(on(1, 88.0) + on(3, -88.0))[1].joint == 1


@pytest.mark.parametrize(
    "steps",
    [3, np.int64(3), np.array(3), np.array([3], np.uint8), np.array([7, 3, 7])[1::2]],
    ids=["int", "numpy int", "0-d", "uint8", "strided"],
)
def test_steps_in_every_integer_form(steps):
    # 2 Nm over 3 cycles: 667 Nm/s, within the rate; over one cycle it would be 2000
    assert torque(on(0, 2.0), steps=steps)[0] == NO_ERROR
