"""The joint side of a Cartesian command: the rows judged on the IK solution of O_T_EE_c
or O_dP_EE_c (docs/fci-behaviour.md "The joint side of a Cartesian command").

===================  =================================================  =====
IK solution          inside the joint range (where it converged)        27
IK solution          per-joint change of velocity / dt                  29
IK solution          velocity inside the envelope at the last solution  28
IK solution          per-joint change of acceleration / dt              30
===================  =================================================  =====

Where these rows stand among the Cartesian ones, and which error the velocity
generator latches for 29 and 30, is the Cartesian tables' (``limits/cartesian.py``).
The acceleration and jerk limits are the robot's per-joint tables times the
discontinuity scale. All functions are pure and batch-first.
"""

from __future__ import annotations

import numpy as np

from ..tables import RobotTable
from .cartesian_derivatives import JointSide


def joint_side_rows(joint: JointSide, table: RobotTable, scale: float):
    """The joint side's four (n,) rows in precedence order (docs/motion-limits.md): the IK
    solution outside the joint range (27, where ``solved``), its acceleration over
    kMaxJointAcceleration (29), its velocity outside the envelope at the previous
    solution (28), its jerk over kMaxJointJerk (30) (the robot's per-joint tables times
    the discontinuity scale; 28 to 30 where ``checked``); None when no row tripped
    anywhere (the common case)."""
    checked = joint.checked
    solved = checked if joint.solved is None else joint.solved
    if not (np.count_nonzero(checked) or np.count_nonzero(solved)):
        return None
    over = np.abs(joint.stacked) > ik_limits(table, scale)  # NaN is not over
    r29, r30 = checked & over[:, 0].any(axis=1), checked & over[:, 1].any(axis=1)
    r27 = r28 = np.zeros(len(checked), dtype=bool)
    if joint.motion is not None:
        q = joint.q
        # Written as "not inside", so a NaN solution trips (as q_c's 12 does).
        r27 = solved & ~((q >= table.q_lower) & (q <= table.q_upper)).all(axis=1)
        r28 = checked & ~_in_envelope(joint, table)
    if not any(np.count_nonzero(row) for row in (r27, r29, r28, r30)):
        return None
    return r27, r29, r28, r30


def range_and_envelope_quiet(joint: JointSide, table: RobotTable) -> bool:
    """Whether no robot's solution is outside the joint range (27, where judged) and no
    robot's IK velocity outside the envelope (28, where ``checked``): the part of the
    Cartesian checks' fast exit that is not a comparison with a fixed limit."""
    if joint.motion is None:
        return True
    rows = joint.checked if joint.solved is None else joint.solved
    if not np.count_nonzero(rows):
        return True
    q = joint.q
    if np.count_nonzero(rows & ~((q >= table.q_lower) & (q <= table.q_upper)).all(axis=1)):
        return False
    return not np.count_nonzero(joint.checked & ~_in_envelope(joint, table))


def _in_envelope(joint: JointSide, table: RobotTable) -> np.ndarray:
    """(n,) the IK velocity inside the joint velocity envelope at the previous solution
    (docs/limits.md §4: at the reference, as 13 for q_c), with libfranka's tolerance."""
    halves = table.velocity_envelope_halves(joint.q_prev)  # [upper | -lower]
    dq = joint.dq
    return (np.concatenate((dq, -dq), axis=1) <= halves).all(axis=1)


def no_joint_rows(n: int) -> tuple[np.ndarray, ...]:
    """Four (n,) joint-side rows that did not trip."""
    return tuple(np.zeros(n, dtype=bool) for _ in range(4))


def ik_limits(table: RobotTable, scale: float) -> np.ndarray:
    """(2, 7) the joint side's acceleration and jerk limits, scaled (cached, read-only)."""
    key = (table.name, scale)
    cached = _IK_LIMITS.get(key)
    if cached is None:
        cached = np.stack((table.ik_ddq_max, table.ik_dddq_max)) * scale
        cached.setflags(write=False)
        _IK_LIMITS[key] = cached
    return cached


_IK_LIMITS: dict[tuple[str, float], np.ndarray] = {}
