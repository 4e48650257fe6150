"""Cartesian motion generators: the O_T_EE_c rows, the O_dP_EE_c rows, the elbow and the
joint side of a Cartesian command (docs/fci-behaviour.md "What is checked, and what it latches").

Rows in precedence order (the first row that trips is the error latched):

==================  ===============================================  =====
O_T_EE_c            homogeneous transformation (refused always)       31
O_T_EE_c            first pose within 0.05 m / 0.1 rad of O_T_EE      16
elbow_c             first elbow within 0.1 rad of q[2], same sign     22
elbow_c             the branch flag elbow_c[1] never flips            21
O_T_EE_c            ||a|| <= 9 m/s^2, ||alpha|| <= 17 rad/s^2         19
O_T_EE_c            ||v|| <= 3 m/s, ||omega|| <= 2.5 rad/s            18
O_T_EE_c            ||jerk|| <= 4500 m/s^3, 8500 rad/s^3              20
IK of O_T_EE_c      inside the joint range                            27
IK of O_T_EE_c      per-joint change of velocity / dt                 29
IK of O_T_EE_c      velocity inside the envelope at the last solution 28
IK of O_T_EE_c      per-joint change of acceleration / dt             30
elbow_c             joint-3 range, velocity, acceleration, jerk       17
==================  ===============================================  =====

==================  ===============================================  =====
O_dP_EE_c           ||a|| <= 9 m/s^2, ||alpha|| <= 17 rad/s^2         20
O_dP_EE_c           ||jerk|| <= 4500 m/s^3, 8500 rad/s^3              20
O_dP_EE_c           ||v|| <= 3 m/s, ||omega|| <= 2.5 rad/s            18
IK of O_dP_EE_c     inside the joint range                            27
IK of O_dP_EE_c     per-joint acceleration and jerk                   30
IK of O_dP_EE_c     velocity inside the envelope at the last solution 28
elbow_c             the branch flag never flips                       21
elbow_c             joint-3 range, velocity, acceleration, jerk       17
==================  ===============================================  =====

The Cartesian limits are norms of the translational and rotational halves
(docs/fci-behaviour.md "What is checked, and what it latches"), with no 0.99 factor on the
rotation (docs/fci-behaviour.md "Two deliberate departures"). The orientation's derivatives
are taken in the body frame — the frame the lost-cycle law composes the
rotation increment in (docs/fci-behaviour.md "What the sim does with a lost cycle") — so an
extrapolated pose stream is differenced onto its own frozen acceleration.

The IK rows (27, 29, 28, 30) are judged by ``limits/cartesian_joint.py``; the tables
here place them. All functions are pure and batch-first; derivatives are backward Euler
over ``steps * dt`` as for q_c (docs/fci-behaviour.md "The difference formulas").
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...sim.rotations import rotation_log
from ..errors import Error
from ..frames import from_wire
from ..tables import RobotTable
from .cartesian_derivatives import (
    ElbowDerivatives,
    ElbowStream,
    JointSide,
    PoseDerivatives,
    Twist,
    elbow_derivatives,
    joint_side,
    pose_derivatives,
)
from .cartesian_joint import ik_limits, joint_side_rows, no_joint_rows, range_and_envelope_quiet
from .record import NO_ERROR, Violation

_E = Error

#: docs/motion-limits.md (the Cartesian pose table) rows after 31 (which is refused on arrival, like
#: a NaN).
POSE_CODES = np.array(
    [
        _E.cartesian_position_motion_generator_start_pose_invalid,  # 16
        _E.cartesian_motion_generator_start_elbow_invalid,  # 22
        _E.cartesian_motion_generator_elbow_sign_inconsistent,  # 21
        _E.cartesian_motion_generator_velocity_discontinuity,  # 19 acceleration
        _E.cartesian_motion_generator_velocity_limits_violation,  # 18 velocity
        _E.cartesian_motion_generator_acceleration_discontinuity,  # 20 jerk
        _E.cartesian_motion_generator_joint_position_limits_violation,  # 27 IK range
        _E.cartesian_motion_generator_joint_velocity_discontinuity,  # 29 IK acceleration
        _E.cartesian_motion_generator_joint_velocity_limits_violation,  # 28 IK envelope
        _E.cartesian_motion_generator_joint_acceleration_discontinuity,  # 30 IK jerk
        _E.cartesian_motion_generator_elbow_limit_violation,  # 17
    ],
    dtype=np.int64,
)
POSE_ROWS = (
    "start pose",
    "start elbow",
    "elbow sign",
    "acceleration",
    "velocity",
    "jerk",
    "IK joint position",
    "IK joint acceleration",
    "IK joint velocity",
    "IK joint jerk",
    "elbow",
)

#: docs/motion-limits.md (the Cartesian velocity table) rows: "everything shifts by one" — both
#: differences are 20.
TWIST_CODES = np.array(
    [
        _E.cartesian_motion_generator_acceleration_discontinuity,  # 20 acceleration
        _E.cartesian_motion_generator_acceleration_discontinuity,  # 20 jerk
        _E.cartesian_motion_generator_velocity_limits_violation,  # 18 velocity
        _E.cartesian_motion_generator_joint_position_limits_violation,  # 27 IK range
        _E.cartesian_motion_generator_joint_acceleration_discontinuity,  # 30 IK acc. and jerk
        _E.cartesian_motion_generator_joint_velocity_limits_violation,  # 28 IK envelope
        _E.cartesian_motion_generator_elbow_sign_inconsistent,  # 21
        _E.cartesian_motion_generator_elbow_limit_violation,  # 17
    ],
    dtype=np.int64,
)
TWIST_ROWS = (
    "acceleration",
    "jerk",
    "velocity",
    "IK joint position",
    "IK joint acceleration",
    "IK joint velocity",
    "elbow sign",
    "elbow",
)

#: Columns of the IK-acceleration row (29) and the IK-jerk row (30) in POSE_CODES. A
#: command that breaks both latches both bits (docs/fci-behaviour.md "The joint side of a
#: Cartesian command").
POSE_IK_ROW = 7
POSE_IK_JERK_ROW = 9


class CartesianCheck(NamedTuple):
    """Result of a Cartesian check: the latched error and every row that tripped."""

    #: (n,) int64 latched Error index, or -1
    error: np.ndarray
    #: (n, rows) bool: which rows tripped (gated by first / later)
    tripped: np.ndarray


def _norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", x, x))


def select(tripped: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """(n,) error of the first tripped row of each robot, -1 where none."""
    first = np.argmax(tripped, axis=1)
    return np.where(tripped.any(axis=1), codes[first], NO_ERROR)


def _elbow_rows(elbow: ElbowStream, later: np.ndarray, table: RobotTable):
    """Rows 21 and 17 (both generators): the branch flag flipping mid-motion; elbow[0]
    outside joint 3's range (always), or its velocity, acceleration or jerk over the
    kMaxElbow* limits (after the first command)."""
    if not np.count_nonzero(elbow.has):  # no elbow this cycle: neither row can trip
        return elbow.has, elbow.has
    continuing = later & elbow.has & elbow.had
    sign = continuing & (elbow.command[:, 1] != elbow.prev_flag)
    e_c, d = elbow.command[:, 0], elbow.derivatives
    out_of_range = ~((e_c >= table.q_lower[2]) & (e_c <= table.q_upper[2]))
    too_fast = (
        (np.abs(d.v) > table.v_elbow_max)
        | (np.abs(d.a) > table.a_elbow_max)
        | (np.abs(d.jerk) > table.j_elbow_max)
    )
    return sign, elbow.has & (out_of_range | (continuing & too_fast))


def _inside(stacked: np.ndarray, table: RobotTable) -> np.ndarray:
    """(n, 6) the norms of (n, 3, 6) [[v | omega], [a | alpha], [jerk | zeta]] within the
    table's limits, in one pass (NaN is not within: it trips)."""
    x = stacked.reshape(len(stacked), 6, 3)
    return np.einsum("nkj,nkj->nk", x, x) <= _limits2(table)


def _quiet(stacked: np.ndarray, joint: JointSide, table: RobotTable, scale: float) -> bool:
    """Whether no Cartesian norm of ``stacked`` (n, 3, 6) is over its limit and no joint-side
    value of any robot (judged or not) is over its own: then neither kind of row trips.

    One comparison of the squared norms (as :func:`_inside` forms them) and the joint
    side's magnitudes side by side; a NaN fails it (the exact rows then decide). Then the
    solution's range and envelope (27, 28), where the joint side judges them.
    """
    n = len(stacked)
    values = np.empty((n, 20))
    x = stacked.reshape(n, 6, 3)
    np.einsum("nkj,nkj->nk", x, x, out=values[:, :6])
    np.abs(joint.stacked.reshape(n, 14), out=values[:, 6:])
    if np.count_nonzero(values <= _quiet_limits(table, scale)) != 20 * n:
        return False
    return range_and_envelope_quiet(joint, table)


def _quiet_limits(table: RobotTable, scale: float) -> np.ndarray:
    """(20,) :func:`_limits2` and the joint side's acceleration and jerk limits, scaled."""
    key = (table.name, scale)
    cached = _QUIET_LIMITS.get(key)
    if cached is None:
        cached = np.concatenate((_limits2(table), ik_limits(table, scale).reshape(14)))
        cached.setflags(write=False)
        _QUIET_LIMITS[key] = cached
    return cached


_QUIET_LIMITS: dict[tuple[str, float], np.ndarray] = {}


def _limits2(table: RobotTable) -> np.ndarray:
    """Squared Cartesian limits [v, omega, a, alpha, jerk, zeta] of ``table``."""
    cached = _LIMITS2.get(table.name)
    if cached is None:
        limits = (
            table.v_trans_max,
            table.v_rot_max,
            table.a_trans_max,
            table.a_rot_max,
            table.j_trans_max,
            table.j_rot_max,
        )
        cached = _LIMITS2[table.name] = np.square(np.array(limits))
    return cached


_LIMITS2: dict[str, np.ndarray] = {}


def check_cartesian_pose(
    d: PoseDerivatives,
    first: np.ndarray,
    T_c: np.ndarray,
    O_T_EE: np.ndarray,
    elbow: ElbowStream,
    elbow_measured: np.ndarray,
    joint: JointSide,
    table: RobotTable,
    scale: float,
    translation_tolerance: float,
    rotation_tolerance: float,
    elbow_tolerance: float,
) -> CartesianCheck:
    """Judge n O_T_EE_c commands (31 is judged on arrival); one latched error per robot.

    Args:
        d: the pose's derivatives (:func:`pose_derivatives`).
        first: (n,) the motion's opening command: the start rows replace the
            derivative rows (the history is rebased at rest on it).
        T_c: (n, 4, 4) commanded poses; O_T_EE: (n, 16) the measured poses as the
            state carries them (read only on an opening command).
        elbow: the elbow stream; elbow_measured (n, 2) the measured (q[2], sign q[3]).
        joint: the IK solution's acceleration and jerk (the joint side, 29 / 30).
        table, scale: the robot's limits; the joint-side tables' scale.
        translation_tolerance, rotation_tolerance, elbow_tolerance: start checks.
    """
    first = np.asarray(first, dtype=bool)
    n = len(first)
    starting = np.count_nonzero(first) > 0
    if not starting and not np.count_nonzero(elbow.has) and _quiet(d.stacked, joint, table, scale):
        return _no_error(n)  # mid-motion, no elbow, nothing near a limit: the common case
    inside = _inside(d.stacked, table)
    joint_rows = joint_side_rows(joint, table, scale)
    later = ~first
    if starting:
        T_m = from_wire(O_T_EE)
        dp = _norm(T_c[:, :3, 3] - T_m[:, :3, 3])
        dr = _norm(rotation_log(T_m[:, :3, :3].transpose(0, 2, 1) @ T_c[:, :3, :3]))
        start_pose = first & ((dp > translation_tolerance) | (dr > rotation_tolerance))
        e_c = elbow.command
        start_elbow = (
            first
            & elbow.has
            & (
                (np.abs(e_c[:, 0] - elbow_measured[:, 0]) > elbow_tolerance)
                | (e_c[:, 1] != elbow_measured[:, 1])
            )
        )
    else:
        start_pose = start_elbow = first
    over = ~inside
    over &= later[:, None]
    ik27, ik29, ik28, ik30 = no_joint_rows(n) if joint_rows is None else joint_rows
    sign, elbow_limit = _elbow_rows(elbow, later, table)
    if not (starting or _any(elbow.has, over, ik27, ik29, ik28, ik30)):
        return _no_error(n)
    vel = over[:, 0] | over[:, 1]
    acc = over[:, 2] | over[:, 3]
    jerk = over[:, 4] | over[:, 5]
    rows = [start_pose, start_elbow, sign, acc, vel, jerk, ik27, ik29, ik28, ik30, elbow_limit]
    tripped = np.stack(rows, axis=1)
    return CartesianCheck(select(tripped, POSE_CODES), tripped)


def check_cartesian_velocity(
    stacked: np.ndarray,
    first: np.ndarray,
    elbow: ElbowStream,
    joint: JointSide,
    table: RobotTable,
    scale: float,
) -> CartesianCheck:
    """Judge n O_dP_EE_c commands; one latched error per robot.

    ``stacked`` (n, 3, 6) is the twist [v | omega] in the base frame, then its first
    and second backward differences against the published O_dP_EE_c history (zero at
    rest, so the opening twist is an acceleration from standstill, as on the robot).
    """
    first = np.asarray(first, dtype=bool)
    n = len(first)
    if not np.count_nonzero(elbow.has) and _quiet(stacked, joint, table, scale):
        return _no_error(n)  # no elbow, nothing near a limit: the common case
    inside = _inside(stacked, table)
    joint_rows = joint_side_rows(joint, table, scale)
    over = ~inside
    ik_range, ik_acc, ik_envelope, ik_jerk = no_joint_rows(n) if joint_rows is None else joint_rows
    sign, elbow_limit = _elbow_rows(elbow, ~first, table)
    if not _any(over, ik_range, ik_acc, ik_envelope, ik_jerk, sign, elbow_limit):
        return _no_error(n)
    vel = over[:, 0] | over[:, 1]
    acc = over[:, 2] | over[:, 3]
    jerk = over[:, 4] | over[:, 5]
    rows = [acc, jerk, vel, ik_range, ik_acc | ik_jerk, ik_envelope, sign, elbow_limit]
    tripped = np.stack(rows, axis=1)
    return CartesianCheck(select(tripped, TWIST_CODES), tripped)


def _any(*tripped: np.ndarray) -> bool:
    """Whether any of the bool arrays has an entry set."""
    return any(np.count_nonzero(x) for x in tripped)


def _no_error(n: int) -> CartesianCheck:
    """No robot tripped a row (``tripped`` is then not built; ``error`` is read-only)."""
    error = _NO_ERRORS.get(n)
    if error is None:
        error = _NO_ERRORS[n] = np.full(n, NO_ERROR, np.int64)
        error.setflags(write=False)
    return CartesianCheck(error, None)


_NO_ERRORS: dict[int, np.ndarray] = {}


def describe_cartesian(i: int, error: int, row: str, quantities: dict) -> Violation:
    """The log line's record for robot i: the row that tripped and its worst quantity.

    ``quantities`` maps a row name to one or more candidates (signal, value (n,) or
    (n, 7), limit, unit); the candidate furthest over its limit is reported (a row
    such as "velocity" judges a translational and a rotational half).
    """
    candidates = quantities[row]
    if isinstance(candidates, tuple):
        candidates = [candidates]
    best = None
    for signal, value, limit, unit in candidates:
        value, limit = np.asarray(value, dtype=np.float64), np.asarray(limit, dtype=np.float64)
        if limit.ndim == value.ndim and limit.ndim > 0:  # a per-robot bound
            limit = limit[i]
        value = np.atleast_1d(value[i])
        limit = np.broadcast_to(np.atleast_1d(limit), value.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(limit != 0, np.abs(value) / np.abs(limit), np.abs(value))
        j = int(np.nanargmax(ratio)) if np.isfinite(ratio).any() else 0
        score = float(ratio[j]) if np.isfinite(ratio[j]) else np.inf
        if best is None or score > best[0]:
            joint = j if value.size == 7 else -1
            best = (
                score,
                Violation(error, signal, joint, float(value[j]), float(limit[j]), unit, row),
            )
    return best[1]


__all__ = [
    "POSE_CODES",
    "POSE_IK_JERK_ROW",
    "POSE_IK_ROW",
    "POSE_ROWS",
    "TWIST_CODES",
    "TWIST_ROWS",
    "CartesianCheck",
    "ElbowDerivatives",
    "ElbowStream",
    "JointSide",
    "PoseDerivatives",
    "Twist",
    "check_cartesian_pose",
    "check_cartesian_velocity",
    "describe_cartesian",
    "elbow_derivatives",
    "joint_side",
    "pose_derivatives",
    "select",
]
