"""Joint motion generators: the q_c rows (11-15) and the dq_c rows (13, 15).

docs/fci-behaviour.md "What is checked, and what it latches", rows in precedence order:

========  ============================================  =====
q_c       inside the joint range                         12
q_c       first q_c matches q_d (start_tolerance)        11
q_c       implied acceleration <= kMaxJointAcceleration   14
q_c       implied velocity inside the envelope at q_d     13
q_c       implied jerk <= kMaxJointJerk                   15
dq_c      first dq_c continues from dq_d                  15
dq_c      implied acceleration                            15
dq_c      implied jerk                                    15
dq_c      dq_c inside the envelope at q_d                 13
========  ============================================  =====

Derivatives are backward Euler (libfranka docs/overview.rst, docs/fci-behaviour.md "The
difference formulas") over ``steps * dt``: dq = (q_c - q_prev) / (steps dt),
ddq = (dq - dq_prev) / (steps dt), dddq = (ddq - ddq_prev) / (steps dt).

The rules' only text is C (fci/limits/_joint.c ``position_rule`` / ``position_detail`` and
``velocity_rule`` / ``velocity_detail``; issue 38: one text per rule, compiled): this module
hands them the table's constants and names the rows they find (:class:`Violation`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ... import native
from ..tables import DELTA_T, JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from .record import Violation

#: the C text of the rules (a required extension: there is no other)
RULES = native.require(
    "fci.limits._joint", "position_rule", "velocity_rule", "position_detail", "velocity_detail"
)

# The rows' names for the log line, in the C text's precedence order (_joint.c: the
# rows, their errors and their order live there; docs/fci-behaviour.md "What is checked,
# and what it latches"). q_c: 12 range, 11 start pose, 14 acceleration, 13 the envelope,
# 15 jerk ("a 1 rad step in q_c is 14, never 13"). dq_c: 13 non-finite (ours, first), 15
# start velocity, acceleration and jerk ("a 50 rad/s step in dq_c is 15, never 13 or 14"),
# 13 the envelope. (check, signal, unit) by row.
_POSITION_ROWS = (
    ("range", "q_c", "rad"),
    ("start pose", "q_c - q_d", "rad"),
    ("acceleration", "q_c", "rad/s^2"),
    ("velocity", "q_c", "rad/s"),
    ("jerk", "q_c", "rad/s^3"),
)
_VELOCITY_ROWS = (
    ("non-finite", "dq_c", "rad/s"),
    ("start velocity", "dq_c - dq_d", "rad/s"),
    ("acceleration", "dq_c", "rad/s^2"),
    ("jerk", "dq_c", "rad/s^3"),
    ("velocity", "dq_c", "rad/s"),
)


def _arguments(table: RobotTable, start_tolerance: float) -> tuple:
    """The C texts' trailing arguments: constants, positional, tolerance, shift, dt."""
    constants, positional = table.joint_constants
    return constants, positional, start_tolerance, JOINT_VELOCITY_LIMIT_TOLERANCE, DELTA_T


def _flags(first):
    """``first`` as the C text reads it: a Python bool, or a bool array (anything else,
    e.g. a list or a float array, converted as numpy's bool conversion reads it)."""
    if isinstance(first, bool) or (isinstance(first, np.ndarray) and first.dtype == np.bool_):
        return first
    return np.asarray(first, dtype=bool)


def _violation(rows, found) -> Violation | None:
    if found is None:
        return None
    error, k, joint, value, limit = found
    check, signal, unit = rows[k]
    if not np.isfinite(value):
        # NaN / inf has no distance to a bound (docs/fci-behaviour.md: a non-finite command is
        # "the limits violation of the generator"): the first such joint, limit NaN.
        check = "non-finite"
    return Violation(error, signal, joint, value, limit, unit, check)


class PositionCheck(NamedTuple):
    """Result of :func:`check_joint_position`."""

    #: (n,) int64: the latched Error index, or -1.
    error: np.ndarray
    #: (n, 7) implied velocity / acceleration, zero on a first command (at rest).
    dq: np.ndarray
    ddq: np.ndarray


class VelocityCheck(NamedTuple):
    """Result of :func:`check_joint_velocity`."""

    #: (n,) int64: the latched Error index, or -1.
    error: np.ndarray
    #: (n, 7) implied acceleration, zero on a first command (at rest).
    ddq: np.ndarray


def check_joint_position(
    q_c: np.ndarray,
    q_prev: np.ndarray,
    dq_prev: np.ndarray,
    ddq_prev: np.ndarray,
    first: np.ndarray,
    q_start: np.ndarray,
    steps: np.ndarray,
    table: RobotTable,
    start_tolerance: float,
) -> PositionCheck:
    """Judge n joint-position commands; one latched error per robot.

    Args:
        q_c: (n, 7) commanded joint positions [rad].
        q_prev, dq_prev, ddq_prev: (n, 7) the history the command is differenced
            against (the reference published as q_d / dq_d / ddq_d).
        first: (n,) bool, the motion's opening command (start-pose check only,
            no derivative checks).
        q_start: (n, 7) the robot's q_d when the motion started (read where ``first``).
        steps: (n,) int >= 1, published cycles since the command the history sits
            at (or a scalar for all robots).
        table: the robot's limits.
        start_tolerance: start-pose tolerance [rad] (docs/fci-behaviour.md "Two deliberate
        departures": 0.1, a sim choice).

    Returns:
        ``PositionCheck(error, dq, ddq)``: error (n,) int64 is 12, 11, 14, 13, 15
        (first tripped row wins) or -1; dq / ddq the implied derivatives to record
        (zero where ``first``: the history is rebased at rest on the opening
        command). They are meaningless (maybe NaN) for a robot whose error is 12.
    """
    error, dq, ddq = RULES.position_rule(
        q_c, q_prev, dq_prev, ddq_prev, _flags(first), q_start, steps,
        *_arguments(table, start_tolerance),
    )  # fmt: skip
    return PositionCheck(error, dq, ddq)


def describe_joint_position(
    i: int,
    q_c: np.ndarray,
    q_prev: np.ndarray,
    dq_prev: np.ndarray,
    ddq_prev: np.ndarray,
    first: np.ndarray,
    q_start: np.ndarray,
    steps: np.ndarray,
    table: RobotTable,
    start_tolerance: float,
) -> Violation | None:
    """Robot i's violation under :func:`check_joint_position` (same arguments), or None.

    Only for the log line of a robot whose error is not -1; not on the per-cycle path.
    """
    found = RULES.position_detail(
        int(i), q_c, q_prev, dq_prev, ddq_prev, _flags(first), q_start, steps,
        *_arguments(table, start_tolerance),
    )  # fmt: skip
    return _violation(_POSITION_ROWS, found)


def check_joint_velocity(
    dq_c: np.ndarray,
    q_prev: np.ndarray,
    dq_prev: np.ndarray,
    ddq_prev: np.ndarray,
    first: np.ndarray,
    dq_start: np.ndarray,
    steps: np.ndarray,
    table: RobotTable,
    start_tolerance: float,
) -> VelocityCheck:
    """Judge n joint-velocity commands; one latched error per robot.

    Args:
        dq_c: (n, 7) commanded joint velocities [rad/s].
        q_prev: (n, 7) the position reference (q_d) the envelope is evaluated at.
        dq_prev, ddq_prev: (n, 7) the history (dq_d / ddq_d) dq_c is differenced against.
        first: (n,) bool, the motion's opening command: the start-velocity check
            replaces the acceleration and jerk checks; the envelope still applies.
        dq_start: (n, 7) the robot's dq_d when the motion started (read where ``first``).
        steps: (n,) int >= 1, published cycles since the command the history sits at.
        table: the robot's limits.
        start_tolerance: start-velocity tolerance [rad/s] (docs/fci-behaviour.md "Two deliberate
        departures": 0.1, a sim choice).

    Returns:
        ``VelocityCheck(error, ddq)``: error (n,) int64 is 13 (non-finite), 15 (start
        velocity, acceleration, jerk), 13 (envelope) or -1; ddq the implied
        acceleration to record (zero where ``first``).
    """
    error, ddq = RULES.velocity_rule(
        dq_c, q_prev, dq_prev, ddq_prev, _flags(first), dq_start, steps,
        *_arguments(table, start_tolerance),
    )  # fmt: skip
    return VelocityCheck(error, ddq)


def describe_joint_velocity(
    i: int,
    dq_c: np.ndarray,
    q_prev: np.ndarray,
    dq_prev: np.ndarray,
    ddq_prev: np.ndarray,
    first: np.ndarray,
    dq_start: np.ndarray,
    steps: np.ndarray,
    table: RobotTable,
    start_tolerance: float,
) -> Violation | None:
    """Robot i's violation under :func:`check_joint_velocity` (same arguments), or None."""
    found = RULES.velocity_detail(
        int(i), dq_c, q_prev, dq_prev, ddq_prev, _flags(first), dq_start, steps,
        *_arguments(table, start_tolerance),
    )  # fmt: skip
    return _violation(_VELOCITY_ROWS, found)
