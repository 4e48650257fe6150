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

The IK rows (27, 29, 28, 30) judge the IK solution: its position inside the joint range
(where it converged), the per-joint change of its velocity and of its acceleration over
dt against the robot's per-joint kMaxJointAcceleration / kMaxJointJerk times the
discontinuity scale, and its velocity inside the envelope at the previous solution.

Every row but the start rows (16, 22: on a motion's opening command only, numpy below)
has one text, in C: ``fci/limits/_joint.c`` ``cartesian_rule`` (issue 38: no numpy
twin), which these functions hand the table's constants. Derivatives are backward Euler
over ``steps * dt`` as for q_c (docs/fci-behaviour.md "The difference formulas";
``limits/cartesian_derivatives.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ... import native
from ...sim.rotations import rotation_log
from ..errors import Error
from ..frames import from_wire
from ..tables import JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from .cartesian_derivatives import (
    ElbowDerivatives,
    ElbowStream,
    JointSide,
    PoseDerivatives,
    Twist,
    elbow_derivatives,
)
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


#: The rules' C text (fci/limits/_joint.c), loaded once.
_RULES = native.require("fci.limits._joint", "cartesian_rule")
_POSE, _TWIST = 0, 1


def _constants(table: RobotTable, scale: float) -> tuple:
    """The C rule's constants of ``table`` and the joint side's ``scale`` (cached, read-only):
    the squared Cartesian limits [v, omega, a, alpha, jerk, zeta], the elbow's
    kMaxElbow* (velocity, acceleration, jerk), the joint side's (2, 7) acceleration and jerk
    limits, the joint constants and whether the envelope is positional."""
    key = (table.name, scale)
    cached = _CONSTANTS.get(key)
    if cached is None:
        limits = (
            table.v_trans_max,
            table.v_rot_max,
            table.a_trans_max,
            table.a_rot_max,
            table.j_trans_max,
            table.j_rot_max,
        )
        elbow = (table.v_elbow_max, table.a_elbow_max, table.j_elbow_max)
        arrays = (
            np.square(np.array(limits, dtype=np.float64)),
            np.array(elbow, dtype=np.float64),
            np.stack((table.ik_ddq_max, table.ik_dddq_max)).astype(np.float64) * scale,
        )
        for array in arrays:
            array.setflags(write=False)
        constants, positional = table.joint_constants
        cached = _CONSTANTS[key] = (*arrays, constants, positional)
    return cached


_CONSTANTS: dict[tuple[str, float], tuple] = {}


def _table(kind, codes, stacked, first, start_pose, start_elbow, elbow, joint, table, scale):
    """One Cartesian table over n robots (the C rule), as a :class:`CartesianCheck`."""
    limits2, elbow_limits, ik_limits, constants, positional = _constants(table, scale)
    d = elbow.derivatives
    motion = joint.motion
    q, dq = (None, None) if motion is None else (motion[:, 0], motion[:, 1])
    result = _RULES.cartesian_rule(
        kind, codes, stacked, first, start_pose, start_elbow,
        elbow.command, elbow.has, elbow.had, elbow.prev_flag, d.v, d.a, d.jerk,
        joint.stacked, joint.checked, joint.solved, q, dq, joint.q_prev,
        limits2, elbow_limits, ik_limits, constants, positional,
        JOINT_VELOCITY_LIMIT_TOLERANCE,
    )  # fmt: skip
    if result is None:
        return _no_error(len(first))
    return CartesianCheck(*result)


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
        d: the pose's derivatives (fci/cartesian/_history.c ``History.pose_derivatives``).
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
    start_pose = start_elbow = None
    if np.count_nonzero(first):  # the start rows, on an opening command only
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
    return _table(
        _POSE, POSE_CODES, d.stacked, first, start_pose, start_elbow, elbow, joint, table, scale
    )


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
    return _table(_TWIST, TWIST_CODES, stacked, first, None, None, elbow, joint, table, scale)


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
]
