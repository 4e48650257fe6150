"""The safety controller's rules (fci/limits/safety.py ``check_safety``, whose only text is
C): the measured joint velocity (3) and Cartesian speed (4), 4 outranking 3, the robots
bad and in motion (docs/fci-behaviour.md "joint_velocity_violation (3)" and
"cartesian_velocity_violation (4)"), and the log line's details (``describe_safety``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.limits import (
    MEASURED_VELOCITY_MARGIN,
    NO_ERROR,
    PlannedSafety,
    check_safety,
    describe_safety,
)
from franka_sim_gym.fci.tables import DELTA_T, FER, FR3
from tests.limit_rules_helpers import E3, E4, HOME, Z, as_batch, on

# NaN / inf inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")


# --- safety controller: 3 / 4 ----------------------------------------------------


#: the EE at rest: the previous cycle's position is this one's
EE = np.array([[0.3, 0.0, 0.5]])


def _judge(dq=Z, q=HOME, v=(0.0, 0.0, 0.0), margin=MEASURED_VELOCITY_MARGIN, table=FR3):
    """Robot 0's error and its log line's details, the EE moving at ``v`` [m/s]."""
    ee_prev = EE - np.asarray(v, dtype=np.float64) * DELTA_T
    args = (as_batch(dq), as_batch(q), EE, ee_prev)
    check = check_safety(*args, np.ones(1, bool), table, margin)
    # the safety controller's planned call: the same answer on the same arrays
    planned = PlannedSafety(*args, table, margin)
    assert planned.run(np.ones(1, bool)) == check.count
    assert (planned.error.tolist(), planned.bad.tolist()) == (
        check.error.tolist(),
        check.bad.tolist(),
    )
    return int(check.error[0]), describe_safety(0, *args, table, margin)


def _measured_joint(dq, q=HOME, margin=MEASURED_VELOCITY_MARGIN):
    return _judge(dq, q, margin=margin)


def _measured_speed(v):
    return _judge(v=v)


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
    """A cycle that breaks both latches 4 only; each alone is its own error."""
    fast_joint, fast_ee = on(0, 2.8), (3.1, 0.0, 0.0)
    assert [
        _judge(dq, v=v)[0]
        for dq, v in ((fast_joint, fast_ee), (fast_joint, (0, 0, 0)), (on(0, 0), fast_ee))
    ] == [E4, E3, E4]
    assert _judge(fast_joint, v=fast_ee)[1].signal == "|v_EE|"


def test_only_robots_in_motion_are_bad_and_counted():
    dq = np.zeros((4, 7))
    dq[[0, 2], 0] = 2.8  # robots 0 and 2 beyond the envelope
    q, ee = np.tile(HOME, (4, 1)), np.tile(EE, (4, 1))
    check = check_safety(dq, q, ee, ee, np.array([True, True, False, True]), FR3)
    assert check.error.tolist() == [E3, NO_ERROR, E3, NO_ERROR]
    assert check.bad.tolist() == [True, False, False, False] and check.count == 1


def test_the_fer_envelope_is_its_constant_dq_max():
    # FER: |dq| <= 2.175 rad/s on joint 1 whatever q (no position-based envelope)
    near_stop = on(0, 2.8)
    assert _judge(on(0, 2.175 - 1e-3 + 0.09), q=near_stop, table=FER)[0] == NO_ERROR
    assert _judge(on(0, 2.175 - 1e-3 + 0.11), q=near_stop, table=FER)[0] == E3


def test_the_log_line_names_the_joint_furthest_outside():
    # at HOME joint 2's lower bound is -2.080, joint 5's upper 5.259 rad/s (+ 0.1 margin)
    dq = on(1, -2.0800 - 0.2) + on(4, 5.259 + 0.5)
    error, why = _measured_joint(dq)
    assert (error, why.joint, why.check) == (E3, 4, "envelope + margin")
    assert why.limit == pytest.approx(5.359)
    assert why.message().startswith("joint_velocity_violation: dq joint 5 = 5.759 rad/s")
    error, why = _measured_joint(on(1, -2.0800 - 0.2) + on(4, 5.259 + 0.15))
    assert (why.joint, why.limit) == (1, pytest.approx(-2.18, abs=1e-4))  # the lower bound
    assert _measured_joint(on(0, 0.0))[1] is None


def test_non_finite_measured_velocity_is_a_violation():
    assert _measured_joint(on(0, math.nan))[0] == E3
    assert _measured_speed((math.nan, 0.0, 0.0))[0] == E4
    # the log line names the first non-finite joint, before any joint merely outside
    error, why = _measured_joint(on(2, 2.9) + on(5, math.inf))
    assert (error, why.joint, why.check) == (E3, 5, "non-finite")
    # ... also before a joint whose envelope is NaN (its q NaN, its dq finite)
    error, why = _measured_joint(on(5, math.inf), q=HOME + on(2, math.nan))
    assert (error, why.joint, why.check) == (E3, 5, "non-finite")


def test_the_bounds_themselves_pass_and_one_ulp_beyond_trips():
    """<= on every bound: the envelope widened by the margin on both sides, and the speed."""
    upper, lower = (b[0] for b in FR3.velocity_envelope(as_batch(HOME)))
    for margin in (0.0, MEASURED_VELOCITY_MARGIN):
        for j in (0, 3, 5):
            for bound, beyond in ((upper[j] + margin, math.inf), (lower[j] - margin, -math.inf)):
                assert _measured_joint(on(j, bound), margin=margin)[0] == NO_ERROR
                past = math.nextafter(bound, beyond)
                assert _measured_joint(on(j, past), margin=margin)[0] == E3
    # 2.999 m/s exactly: the EE moved 2.999 mm in the cycle (speed computed as the rule does)
    ee_prev = np.zeros((1, 3))
    at = np.array([[2.999 / 1000.0, 0.0, 0.0]])
    past = np.array([[math.nextafter(2.999 / 1000.0, 1.0), 0.0, 0.0]])
    for ee, want in ((at, NO_ERROR), (past, E4)):
        check = check_safety(as_batch(Z), as_batch(HOME), ee, ee_prev, np.ones(1, bool), FR3)
        assert int(check.error[0]) == want


def test_each_robot_is_judged_and_described_on_its_own_rows():
    q, dq = np.tile(HOME, (3, 1)), np.zeros((3, 7))
    dq[2, 3] = 2.8  # robot 2: joint 4 beyond the envelope
    ee = np.tile(EE, (3, 1))
    ee_prev = ee.copy()
    ee_prev[1, 1] -= 3.5 * DELTA_T  # robot 1: the EE at 3.5 m/s
    args = (dq, q, ee, ee_prev)
    check = check_safety(*args, np.ones(3, bool), FR3)
    assert check.error.tolist() == [NO_ERROR, E4, E3] and check.count == 2
    assert describe_safety(0, *args, FR3) is None
    fast = describe_safety(np.int64(1), *args, FR3)  # a numpy index, as np.flatnonzero gives
    assert (fast.signal, fast.value) == ("|v_EE|", pytest.approx(3.5))
    assert (describe_safety(2, *args, FR3).joint, describe_safety(2, *args, FR3).value) == (3, 2.8)
    with pytest.raises(IndexError, match="robot 3 of 3"):
        describe_safety(3, *args, FR3)


def test_a_nan_position_makes_its_joint_the_one_named():
    """A NaN measured q gives that joint a NaN envelope: dq is not within it (3), and the
    log line names that joint, with no finite bound."""
    error, why = _measured_joint(on(1, 2.0), q=HOME + on(2, math.nan))
    assert (error, why.joint, why.check) == (E3, 2, "envelope + margin")
    assert math.isnan(why.limit)


def test_the_planned_check_reads_its_arrays_at_every_run_and_counts_robots_in_motion():
    dq, q = np.zeros((3, 7)), np.tile(HOME, (3, 1))
    ee = np.tile(EE, (3, 1))
    ee_prev = ee.copy()
    planned = PlannedSafety(dq, q, ee, ee_prev, FR3)
    moving = np.array([True, False, True])
    assert planned.run(moving) == 0
    assert planned.error.tolist() == [NO_ERROR] * 3
    dq[0, 0] = dq[1, 0] = 3.0  # joint 1 past its envelope on robots 0 and 1
    ee_prev[2] -= (0.0, 0.0, 4.0 * DELTA_T)  # robot 2's EE at 4 m/s
    assert planned.run(moving) == 2  # robot 1 is not in motion: judged, not counted
    assert planned.error.tolist() == [E3, E3, E4]
    assert planned.bad.tolist() == [True, False, True]
    dq[...] = 0.0
    ee_prev[...] = ee
    assert planned.run(moving) == 0 and not planned.bad.any()


def test_the_planned_check_refuses_bad_arrays_by_name():
    from franka_sim_gym.fci.limits.safety import RULES

    dq, q, ee = np.zeros((2, 7)), np.tile(HOME, (2, 1)), np.zeros((2, 3))
    constants, positional = FR3.joint_constants
    head = (dq, q, ee, ee.copy(), constants, positional, 0.0, 0.1, 3.0, DELTA_T)
    with pytest.raises(ValueError, match="error"):
        RULES.SafetyPlan(*head, np.zeros(2, np.int32), np.zeros(2, np.uint8))
    with pytest.raises(ValueError, match="bad"):
        RULES.SafetyPlan(*head, np.zeros(2, np.int64), np.zeros(2, np.int16))
    with pytest.raises(ValueError, match="ee_prev"):
        RULES.SafetyPlan(*head[:3], np.zeros((2, 2)), *head[4:], np.zeros(2, np.int64),
                         np.zeros(2, np.uint8))  # fmt: skip
    plan = RULES.SafetyPlan(*head, np.zeros(2, np.int64), np.zeros(2, np.uint8))
    with pytest.raises(ValueError, match="in_motion"):
        plan.run(np.zeros(3, bool))
