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

The rows' per-joint arithmetic (the differences, the envelope, the comparisons) has a C
replacement, ``fci/limits/_joint.c``, chosen by the backend switch (:data:`KERNEL`,
``native.load``): it returns which rows trip per robot, and the precedence table below
picks the error from them as it does on the numpy path, bit for bit the same
(tests/fci/test_joint_rules_parity.py; docs/architecture.md "One implementation per
rule" says why).
"""

from __future__ import annotations

from types import ModuleType
from typing import NamedTuple

import numpy as np

from ... import native
from ..errors import Error
from ..tables import JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from .precedence import (
    NO_ERROR,
    Precedence,
    Row,
    Violation,
    as_bool,
    describe_row,
    interval,
    robot_row,
    stack,
)

_E = Error

# docs/fci-behaviour.md "What is checked, and what it latches", joint-position rows in precedence
# order. 12 comes before 11 ("Start-pose outranks every discontinuity ... It does not outrank the
# joint-range check": a sim ordering, no hardware evidence), 11 before every
# discontinuity, and the discontinuity (14) before the envelope (13) ("a 1 rad
# step in q_c is 14, never 13"). 15 last, as docs/motion-limits.md lists it. The
# start-pose row applies only to a motion's first command; the derivative rows
# only after it (the motion starts at rest: the start-pose check is the check).
_POSITION = Precedence(
    codes=(
        _E.joint_motion_generator_position_limits_violation,  # 12 range (and non-finite)
        _E.joint_position_motion_generator_start_pose_invalid,  # 11 start pose
        _E.joint_motion_generator_velocity_discontinuity,  # 14 acceleration
        _E.joint_motion_generator_velocity_limits_violation,  # 13 envelope
        _E.joint_motion_generator_acceleration_discontinuity,  # 15 jerk
    ),
    first_only=(1,),
    later_only=(2, 3, 4),
)

# docs/fci-behaviour.md "Which discontinuity you get depends on the interface": on dq_c both the
# first and the second difference are named 15 ("a 50 rad/s step in dq_c is 15,
# never 13 or 14"), and every discontinuity outranks the envelope (13). Row 0,
# non-finite, is ours: docs/fci-behaviour.md "What is checked, and what it latches" names it the
# generator's limits violation (13); it must come first, since inf would otherwise read as a 15
# step and NaN would pass every `>` comparison below.
_VELOCITY = Precedence(
    codes=(
        _E.joint_motion_generator_velocity_limits_violation,  # 13 non-finite
        _E.joint_motion_generator_acceleration_discontinuity,  # 15 start velocity
        _E.joint_motion_generator_acceleration_discontinuity,  # 15 acceleration
        _E.joint_motion_generator_acceleration_discontinuity,  # 15 jerk
        _E.joint_motion_generator_velocity_limits_violation,  # 13 envelope
    ),
    first_only=(1,),
    later_only=(2, 3),
)


#: The C replacement of the rows' arithmetic (fci/limits/_joint.c), or None where it was
#: not built or the backend switch is off: the numpy rules below run.
KERNEL: ModuleType | None = native.load("fci.limits._joint")

_CONSTANTS: dict[int, tuple[RobotTable, np.ndarray, float]] = {}


def joint_constants(table: RobotTable) -> tuple[np.ndarray, float]:
    """The table's joint limits as the C replacement takes them: (7, 7) rows q_lower,
    q_upper, ddq_max, dddq_max, 2 ddq_decel, dq_offset, dq_max, and 1.0 where the envelope
    depends on the position (0.0: the constant dq_max of a robot without offsets)."""
    cached = _CONSTANTS.get(id(table))
    if cached is None or cached[0] is not table:
        positional = table.dq_offset is not None
        zero = np.zeros(7)
        rows = (
            table.q_lower,
            table.q_upper,
            table.ddq_max,
            table.dddq_max,
            2.0 * table.ddq_decel if positional else zero,
            table.dq_offset if positional else zero,
            table.dq_max,
        )
        cached = (table, np.ascontiguousarray(np.stack(rows), dtype=np.float64), float(positional))
        cached[1].setflags(write=False)
        _CONSTANTS[id(table)] = cached
    return cached[1], cached[2]


def _h(steps) -> float | np.ndarray:
    """The differencing interval as the kernel takes it: one float, or (n,)."""
    h = interval(steps)
    return h if isinstance(h, float) else np.ascontiguousarray(h.reshape(-1))


def _kernel_position(kernel, q_c, q_prev, dq_prev, ddq_prev, first, q_start, steps, table, tol):
    n = len(q_c)
    rows, dq, ddq = np.empty(n, np.uint8), np.empty((n, 7)), np.empty((n, 7))
    constants, positional = joint_constants(table)
    starting = np.count_nonzero(first) > 0
    kernel.position_rows(
        q_c, q_prev, dq_prev, ddq_prev, q_start if starting else None, _h(steps),
        constants, positional, tol, JOINT_VELOCITY_LIMIT_TOLERANCE, rows, dq, ddq,
    )  # fmt: skip
    if not starting:
        if not np.count_nonzero(rows):
            return PositionCheck(np.full(n, NO_ERROR, np.int64), dq, ddq)
        return PositionCheck(_POSITION.lut[0, rows], dq, ddq)
    at_rest = first.reshape(-1, 1)
    error = _POSITION.lut[first.view(np.uint8), rows]
    return PositionCheck(error, np.where(at_rest, 0.0, dq), np.where(at_rest, 0.0, ddq))


def _kernel_velocity(kernel, dq_c, q_prev, dq_prev, ddq_prev, first, dq_start, steps, table, tol):
    n = len(dq_c)
    rows, ddq = np.empty(n, np.uint8), np.empty((n, 7))
    constants, positional = joint_constants(table)
    starting = np.count_nonzero(first) > 0
    kernel.velocity_rows(
        dq_c, q_prev, dq_prev, ddq_prev, dq_start if starting else None, _h(steps),
        constants, positional, tol, JOINT_VELOCITY_LIMIT_TOLERANCE, rows, ddq,
    )  # fmt: skip
    if not starting:
        if not np.count_nonzero(rows):
            return VelocityCheck(np.full(n, NO_ERROR, np.int64), ddq)
        return VelocityCheck(_VELOCITY.lut[0, rows], ddq)
    error = _VELOCITY.lut[first.view(np.uint8), rows]
    return VelocityCheck(error, np.where(first.reshape(-1, 1), 0.0, ddq))


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


def _position_terms(
    q_c, q_prev, dq_prev, ddq_prev, q_start, steps, table, start_tolerance, envelope=None
):
    """Per-joint masks of the five rows (the start row None when ``q_start`` is None)."""
    h = interval(steps)
    dq = (q_c - q_prev) / h
    ddq = (dq - dq_prev) / h
    dddq = (ddq - ddq_prev) / h
    # docs/limits.md §4: the envelope is evaluated at the reference (q_d), never at q.
    upper, lower = table.velocity_envelope(q_prev) if envelope is None else envelope
    masks = [
        # Written as "not inside", so NaN lands here (docs/fci-behaviour.md: a non-finite command is
        # "the limits violation of the generator it arrived in", i.e. 12 for q_c).
        ~((q_c >= table.q_lower) & (q_c <= table.q_upper)),
        None if q_start is None else np.abs(q_c - q_start) > start_tolerance,
        np.abs(ddq) > table.ddq_max,
        (dq > upper) | (dq < lower),
        np.abs(dddq) > table.dddq_max,
    ]
    return masks, dq, ddq, dddq, upper, lower


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
    envelope: tuple[np.ndarray, np.ndarray] | None = None,
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
        departures": 0.1, a sim choice). envelope: ``table.velocity_envelope(q_prev)`` when the
        caller already has it.

    Returns:
        ``PositionCheck(error, dq, ddq)``: error (n,) int64 is 12, 11, 14, 13, 15
        (first tripped row wins) or -1; dq / ddq the implied derivatives to record
        (zero where ``first``: the history is rebased at rest on the opening
        command). They are meaningless (maybe NaN) for a robot whose error is 12.
    """
    first = as_bool(first)
    if KERNEL is not None and envelope is None:
        return _kernel_position(
            KERNEL, q_c, q_prev, dq_prev, ddq_prev, first, q_start, steps, table,
            start_tolerance,
        )  # fmt: skip
    starting = bool(first.any())
    masks, dq, ddq, _, _, _ = _position_terms(
        q_c,
        q_prev,
        dq_prev,
        ddq_prev,
        q_start if starting else None,
        steps,
        table,
        start_tolerance,
        envelope,
    )
    if not starting:
        # Mid-motion, the common case: all-or-none. (The start row cannot apply.)
        r12, _, r14, r13, r15 = masks
        if not (r12 | r14 | r13 | r15).any():
            return PositionCheck(np.full(dq.shape[0], NO_ERROR, np.int64), dq, ddq)
        masks[1] = np.zeros_like(r12)
    error = _POSITION.select(stack(*masks), first)
    if starting:
        at_rest = first.reshape(-1, 1)
        dq, ddq = np.where(at_rest, 0.0, dq), np.where(at_rest, 0.0, ddq)
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
    args = [robot_row(a, i) for a in (q_c, q_prev, dq_prev, ddq_prev, q_start, steps)]
    q_c, q_prev, dq_prev, ddq_prev, q_start, steps = args
    is_first = bool(robot_row(first, i).reshape(-1)[0])
    masks, dq, ddq, dddq, upper, lower = _position_terms(
        q_c, q_prev, dq_prev, ddq_prev, q_start, steps, table, start_tolerance
    )
    tripped = stack(*masks)
    k = _POSITION.first_row(tripped[0], is_first)
    if k is None:
        return None
    tol = start_tolerance
    row = (
        Row(12, "range", "q_c", "rad", q_c, table.q_upper, table.q_lower),
        Row(11, "start pose", "q_c - q_d", "rad", q_c - q_start, tol, -tol, symmetric=True),
        Row(14, "acceleration", "q_c", "rad/s^2", ddq, table.ddq_max, -table.ddq_max, True),
        Row(13, "velocity", "q_c", "rad/s", dq, upper, lower),
        Row(15, "jerk", "q_c", "rad/s^3", dddq, table.dddq_max, -table.dddq_max, True),
    )[k]
    return describe_row(row, tripped[0, k])


def _velocity_terms(dq_c, q_prev, dq_prev, ddq_prev, dq_start, steps, table, start_tolerance):
    """Per-joint masks of the five rows (the start row None when ``dq_start`` is None)."""
    h = interval(steps)
    ddq = (dq_c - dq_prev) / h
    dddq = (ddq - ddq_prev) / h
    # docs/limits.md §4: evaluated at q_d on the joint-velocity interface.
    upper, lower = table.velocity_envelope(q_prev)
    masks = [
        ~np.isfinite(dq_c),
        None if dq_start is None else np.abs(dq_c - dq_start) > start_tolerance,
        np.abs(ddq) > table.ddq_max,
        np.abs(dddq) > table.dddq_max,
        # "not inside": NaN trips it too, which is what sends a NaN off the
        # all-or-none path below (the non-finite row then names it 13).
        ~((dq_c <= upper) & (dq_c >= lower)),
    ]
    return masks, ddq, dddq, upper, lower


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
    first = as_bool(first)
    if KERNEL is not None:
        return _kernel_velocity(
            KERNEL, dq_c, q_prev, dq_prev, ddq_prev, first, dq_start, steps, table,
            start_tolerance,
        )  # fmt: skip
    starting = bool(first.any())
    masks, ddq, _, _, _ = _velocity_terms(
        dq_c,
        q_prev,
        dq_prev,
        ddq_prev,
        dq_start if starting else None,
        steps,
        table,
        start_tolerance,
    )
    if not starting:
        # Mid-motion: all-or-none. NaN trips the envelope row, inf the
        # acceleration row, so a non-finite dq_c never passes here.
        _, _, r15a, r15j, r13 = masks
        if not (r15a | r15j | r13).any():
            return VelocityCheck(np.full(ddq.shape[0], NO_ERROR, np.int64), ddq)
        masks[1] = np.zeros_like(r13)
    error = _VELOCITY.select(stack(*masks), first)
    if starting:
        ddq = np.where(first.reshape(-1, 1), 0.0, ddq)
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
    args = [robot_row(a, i) for a in (dq_c, q_prev, dq_prev, ddq_prev, dq_start, steps)]
    dq_c, q_prev, dq_prev, ddq_prev, dq_start, steps = args
    is_first = bool(robot_row(first, i).reshape(-1)[0])
    masks, ddq, dddq, upper, lower = _velocity_terms(
        dq_c, q_prev, dq_prev, ddq_prev, dq_start, steps, table, start_tolerance
    )
    tripped = stack(*masks)
    k = _VELOCITY.first_row(tripped[0], is_first)
    if k is None:
        return None
    tol = start_tolerance
    inf = np.inf
    row = (
        Row(13, "non-finite", "dq_c", "rad/s", dq_c, inf, -inf),
        Row(15, "start velocity", "dq_c - dq_d", "rad/s", dq_c - dq_start, tol, -tol, True),
        Row(15, "acceleration", "dq_c", "rad/s^2", ddq, table.ddq_max, -table.ddq_max, True),
        Row(15, "jerk", "dq_c", "rad/s^3", dddq, table.dddq_max, -table.dddq_max, True),
        Row(13, "velocity", "dq_c", "rad/s", dq_c, upper, lower),
    )[k]
    return describe_row(row, tripped[0, k])
