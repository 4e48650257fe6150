"""The torque rules (fci/limits/torque.py): tau_J_d's range (34) and rate (32), one
provocation and one conforming twin per row (docs/fci-behaviour.md "What is checked, and
what it latches")."""

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
    args = (as_batch(tau_c), as_batch(tau_prev), np.array([first]), np.array([steps]), FR3)
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
