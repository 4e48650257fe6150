"""A Cartesian step judged by its generator's precedence table (limits/cartesian.py).

The rules return one error per robot and the rows that tripped; this module hands
them to the engine with what the log line names (the row's worst quantity), and 30
beside 29 when one command breaks both (docs/fci-behaviour.md "The joint side of a Cartesian
command").
"""

from __future__ import annotations

import numpy as np

from ..config import ControllerConfig
from ..engine import MotionLimitEngine
from ..errors import Error
from ..limits import cartesian as rules
from ..modes import Modes
from ..state import StateWriter
from .step import Step


class CartesianChecks:
    """Judges Cartesian steps of n robots: logged, enforced (through the engine)."""

    def __init__(
        self, modes: Modes, config: ControllerConfig, writer: StateWriter, engine: MotionLimitEngine
    ) -> None:
        self.modes = modes
        self.config = config
        self.table = config.table
        self.writer = writer
        self.engine = engine

    def check(self, step: Step, first: np.ndarray, active: np.ndarray) -> None:
        """Judge ``active``'s step by its generator's precedence table."""
        m = self.modes
        if m.n_cartesian_position:
            pose = active & m.cartesian_position
            if np.count_nonzero(pose):
                self._check_pose(step, first, pose)
        if m.n_cartesian_velocity:
            twist = active & m.cartesian_velocity
            if np.count_nonzero(twist):
                self._check_twist(step, first, twist)

    def _check_twist(self, step: Step, first: np.ndarray, rows: np.ndarray) -> None:
        """The O_dP_EE_c table (20, 20, 18, 30, 21, 17) over ``rows``."""
        table, scale = self.table, self.config.joint_discontinuity_scale
        check = rules.check_cartesian_velocity(
            step.twist_stack, first, step.elbow, step.joint, table, scale
        )
        if check.tripped is None:  # nothing tripped (the common case)
            return

        def twist_quantities() -> dict:  # built only for a log line
            ik = _joint_position_quantities("IK(O_dP_EE_c)", step.joint, table)
            twist, dtwist, ddtwist = (step.twist_stack[:, k] for k in range(3))
            joint, elbow = step.joint, step.elbow
            return {
                "acceleration": [
                    ("O_dP_EE_c", _norm3(dtwist[:, :3]), table.a_trans_max, "m/s^2"),
                    ("O_dP_EE_c rotation", _norm3(dtwist[:, 3:]), table.a_rot_max, "rad/s^2"),
                ],
                "jerk": [
                    ("O_dP_EE_c", _norm3(ddtwist[:, :3]), table.j_trans_max, "m/s^3"),
                    ("O_dP_EE_c rotation", _norm3(ddtwist[:, 3:]), table.j_rot_max, "rad/s^3"),
                ],
                "velocity": [
                    ("O_dP_EE_c", _norm3(twist[:, :3]), table.v_trans_max, "m/s"),
                    ("O_dP_EE_c rotation", _norm3(twist[:, 3:]), table.v_rot_max, "rad/s"),
                ],
                "IK joint acceleration": [
                    ("IK(O_dP_EE_c)", joint.ddq, table.ik_ddq_max * scale, "rad/s^2"),
                    ("IK(O_dP_EE_c)", joint.dddq, table.ik_dddq_max * scale, "rad/s^3"),
                ],
                **ik,
                "elbow sign": ("elbow_c[1]", elbow.command[:, 1], elbow.prev_flag, ""),
                "elbow": _elbow_quantities(elbow.command, elbow.derivatives, table),
            }

        self._judge(check, rows, rules.TWIST_ROWS, twist_quantities, None)

    def _check_pose(self, step: Step, first: np.ndarray, rows: np.ndarray) -> None:
        """The O_T_EE_c table (16, 22, 21, 19, 18, 20, 29, 30, 17) over ``rows``."""
        w, cfg = self.writer, self.config
        table, scale = self.table, cfg.joint_discontinuity_scale
        d, T_cand, elbow, joint = step.d, step.T, step.elbow, step.joint
        check = rules.check_cartesian_pose(
            d,
            first,
            T_cand,
            w.O_T_EE,
            elbow,
            w.elbow,
            joint,
            table,
            scale,
            cfg.cartesian_start_translation_tolerance,
            cfg.cartesian_start_rotation_tolerance,
            cfg.start_elbow_tolerance,
        )
        if check.tripped is None:  # nothing tripped (the common case)
            return

        def pose_quantities() -> dict:  # built only for a log line
            ik = _joint_position_quantities("IK(O_T_EE_c)", joint, table)
            return {
                **ik,
                "start pose": (
                    "O_T_EE_c - O_T_EE (translation)",
                    _norm3(T_cand[:, :3, 3] - w.O_T_EE[:, 12:15]),
                    cfg.cartesian_start_translation_tolerance,
                    "m",
                ),
                "start elbow": (
                    "elbow_c[0] - q[2]",
                    elbow.command[:, 0] - w.elbow[:, 0],
                    cfg.start_elbow_tolerance,
                    "rad",
                ),
                "elbow sign": ("elbow_c[1]", elbow.command[:, 1], elbow.prev_flag, ""),
                "acceleration": [
                    ("O_T_EE_c", _norm3(d.a), table.a_trans_max, "m/s^2"),
                    ("O_T_EE_c rotation", _norm3(d.alpha), table.a_rot_max, "rad/s^2"),
                ],
                "velocity": [
                    ("O_T_EE_c", _norm3(d.v), table.v_trans_max, "m/s"),
                    ("O_T_EE_c rotation", _norm3(d.omega), table.v_rot_max, "rad/s"),
                ],
                "jerk": [
                    ("O_T_EE_c", _norm3(d.jerk), table.j_trans_max, "m/s^3"),
                    ("O_T_EE_c rotation", _norm3(d.zeta), table.j_rot_max, "rad/s^3"),
                ],
                "IK joint acceleration": (
                    "IK(O_T_EE_c)",
                    joint.ddq,
                    table.ik_ddq_max * scale,
                    "rad/s^2",
                ),
                "IK joint jerk": ("IK(O_T_EE_c)", joint.dddq, table.ik_dddq_max * scale, "rad/s^3"),
                "elbow": _elbow_quantities(elbow.command, elbow.derivatives, table),
            }

        self._judge(check, rows, rules.POSE_ROWS, pose_quantities, rules.POSE_IK_ROW)

    def _judge(self, check, rows, names, quantities, ik_row) -> None:
        """Name each violation's row for the log; 29 brings 30 when one command breaks both."""
        error = check.error
        if not np.count_nonzero(rows & (error >= 0)):
            return

        def describe(i: int):
            k = int(np.argmax(check.tripped[i]))
            return rules.describe_cartesian(i, int(error[i]), names[k], quantities())

        extra = None
        if ik_row is not None:
            both = check.tripped[:, ik_row] & check.tripped[:, rules.POSE_IK_JERK_ROW]
            both &= error == rules.POSE_CODES[ik_row]
            if np.count_nonzero(both):
                extra = {
                    i: [int(Error.cartesian_motion_generator_joint_acceleration_discontinuity)]
                    for i in np.flatnonzero(both).tolist()
                }
        self.engine.judge(error, rows, describe, extra)


def _joint_position_quantities(signal: str, joint, table) -> dict:
    """The log line's candidates of rows 27 and 28: how far the IK solution is beyond its
    joint range, and its velocity against the envelope bound on its side."""
    if joint.motion is None:
        return {}
    q, dq = joint.q, joint.dq
    beyond = np.maximum(np.maximum(table.q_lower - q, q - table.q_upper), 0.0)
    upper, lower = table.velocity_envelope(joint.q_prev)
    bound = np.where(dq >= 0.0, upper, lower)
    return {
        "IK joint position": (f"{signal} beyond the joint range", beyond, 0.0, "rad"),
        "IK joint velocity": (f"{signal} velocity", dq, bound, "rad/s"),
    }


def _norm3(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", x, x))


def _elbow_quantities(elbow: np.ndarray, de, table) -> list:
    """Row 17's candidates for the log line: range, velocity, acceleration, jerk."""
    return [
        ("elbow_c[0]", elbow[:, 0], table.q_upper[2], "rad"),
        ("elbow_c[0] velocity", de.v, table.v_elbow_max, "rad/s"),
        ("elbow_c[0] acceleration", de.a, table.a_elbow_max, "rad/s^2"),
        ("elbow_c[0] jerk", de.jerk, table.j_elbow_max, "rad/s^3"),
    ]
