"""The joint rules batch-first (fci/limits/joint.py): robots in one call are independent,
a random batch matches the row-by-row reading of the q_c / dq_c tables of
docs/motion-limits.md, and one call runs the same Python lines for any number of robots."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci.limits import (
    NO_ERROR,
    check_joint_position,
    check_joint_velocity,
    describe_joint_velocity,
)
from franka_sim_gym.fci.tables import FR3
from tests.limit_rules_helpers import DT, E11, E12, E13, E14, E15, HOME, TOL, Z, moving, on

# NaN / inf inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")


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


def _lines(fn) -> int:
    """How many Python lines ``fn()`` executes (sys.settrace's line events): a loop over
    robots or joints executes its body once per robot, a numpy call once."""
    fn()  # warm: lazy imports and caches out of the count
    count = 0

    def trace(frame, event, arg):
        nonlocal count
        count += event == "line"
        return trace

    sys.settrace(trace)
    try:
        fn()
    finally:
        sys.settrace(None)
    return count


def test_one_call_per_cycle_runs_the_same_lines_for_one_robot_and_for_256():
    """Batch first (docs/architecture.md "Batch first"): judging 256 robots executes
    exactly the Python lines judging one does, i.e. no Python loop over robots or joints
    on the clean path. Counted, not timed (speed lives in benchmarks/)."""

    def call(n):
        q = np.tile(HOME, (n, 1))
        zero = np.zeros((n, 7))
        first = np.zeros(n, dtype=bool)
        steps = np.ones(n, dtype=np.int64)
        return lambda: check_joint_position(q, q, zero, zero, first, q, steps, FR3, TOL)

    one, many = _lines(call(1)), _lines(call(256))
    assert 0 < one < 200
    assert many == one
