"""The UDP wire layouts of robot server v10 as numpy structured dtypes, and the mode enums.

"State is the wire" (design/architecture.md): the controller keeps its published
RobotState in an array of ``ROBOT_STATE_DTYPE`` and the socket server sends
``states[i].tobytes()``; commands arrive as ``ROBOT_COMMAND_DTYPE`` records.
All layouts are little-endian and packed (docs/wire-protocol.md conventions).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

__all__ = [
    "ROBOT_STATE_SIZE",
    "ROBOT_COMMAND_SIZE",
    "GRIPPER_STATE_SIZE",
    "ROBOT_STATE_DTYPE",
    "ROBOT_COMMAND_DTYPE",
    "GRIPPER_STATE_DTYPE",
    "RobotMode",
    "MotionGeneratorMode",
    "ControllerMode",
    "MoveControllerMode",
    "MoveMotionGeneratorMode",
    "state_motion_generator_mode",
    "state_controller_mode",
]

ROBOT_STATE_SIZE = 1377
ROBOT_COMMAND_SIZE = 371
GRIPPER_STATE_SIZE = 23

_F32 = "<f4"
_F64 = "<f8"
_BOOL = "?"  # one byte, 0 or 1, for every bool / bool[] field on the wire
_U8 = "u1"

# §7: UDP RobotState, v10 (libfranka-common rbk_types.h d96c221). A list of
# (name, format, shape) packs naturally: numpy adds no padding unless align=True.
ROBOT_STATE_DTYPE = np.dtype(
    [
        ("message_id", "<u8"),
        ("O_T_EE", _F32, (16,)),
        ("O_T_EE_d", _F32, (16,)),
        ("F_T_EE", _F32, (16,)),
        ("EE_T_K", _F32, (16,)),
        ("F_T_NE", _F32, (16,)),
        ("NE_T_EE", _F32, (16,)),
        ("m_ee", _F32),
        ("I_ee", _F32, (9,)),
        ("F_x_Cee", _F32, (3,)),
        ("m_load", _F32),
        ("I_load", _F32, (9,)),
        ("F_x_Cload", _F32, (3,)),
        ("elbow", _F32, (2,)),
        ("elbow_d", _F32, (2,)),
        ("tau_J", _F32, (7,)),
        ("tau_J_d", _F32, (7,)),
        ("dtau_J", _F32, (7,)),
        ("q", _F32, (7,)),
        ("q_d", _F32, (7,)),
        ("dq", _F32, (7,)),
        ("dq_d", _F32, (7,)),
        ("ddq_d", _F32, (7,)),
        ("joint_contact", _F32, (7,)),
        ("cartesian_contact", _F32, (6,)),
        ("joint_collision", _F32, (7,)),
        ("cartesian_collision", _F32, (6,)),
        ("tau_ext_hat_filtered", _F32, (7,)),
        ("O_F_ext_hat_K", _F32, (6,)),
        ("K_F_ext_hat_K", _F32, (6,)),
        ("O_dP_EE_d", _F32, (6,)),
        ("O_ddP_O", _F32, (3,)),
        ("elbow_c", _F32, (2,)),
        ("delbow_c", _F32, (2,)),
        ("ddelbow_c", _F32, (2,)),
        ("O_T_EE_c", _F32, (16,)),
        ("O_dP_EE_c", _F32, (6,)),
        ("O_ddP_EE_c", _F32, (6,)),
        ("theta", _F32, (7,)),
        ("dtheta", _F32, (7,)),
        # joints 1-6 x (x, y, z); row-major, element [i][k] at 1144 + 12 i + 4 k
        ("accelerometer_top", _F32, (6, 3)),
        ("accelerometer_bottom", _F32, (6, 3)),
        ("motion_generator_mode", _U8),  # MotionGeneratorMode (§7.1)
        ("controller_mode", _U8),  # ControllerMode (§7.1)
        ("errors", _BOOL, (41,)),  # index = errors.Error
        ("reflex_reason", _BOOL, (41,)),
        ("robot_mode", _U8),  # RobotMode (§7.1)
        ("control_command_success_rate", _F32),
    ]
)

# §8: UDP RobotCommand, client -> server. libfranka nests these in `motion` /
# `control`; the names here are flat (no field name repeats).
ROBOT_COMMAND_DTYPE = np.dtype(
    [
        ("message_id", "<u8"),
        ("q_c", _F64, (7,)),
        ("dq_c", _F64, (7,)),
        ("O_T_EE_c", _F64, (16,)),
        ("O_dP_EE_c", _F64, (6,)),
        ("elbow_c", _F64, (2,)),
        ("valid_elbow", _BOOL),
        ("motion_generation_finished", _BOOL),
        ("tau_J_d", _F64, (7,)),
        ("torque_command_finished", _BOOL),
    ]
)

# §10.3: gripper state datagram (gripper server v3).
GRIPPER_STATE_DTYPE = np.dtype(
    [
        ("message_id", "<u4"),
        ("width", _F64),
        ("max_width", _F64),
        ("is_grasped", _BOOL),
        ("temperature", "<u2"),
    ]
)

assert ROBOT_STATE_DTYPE.itemsize == ROBOT_STATE_SIZE, ROBOT_STATE_DTYPE.itemsize
assert ROBOT_COMMAND_DTYPE.itemsize == ROBOT_COMMAND_SIZE, ROBOT_COMMAND_DTYPE.itemsize
assert GRIPPER_STATE_DTYPE.itemsize == GRIPPER_STATE_SIZE, GRIPPER_STATE_DTYPE.itemsize


class RobotMode(IntEnum):
    """State ``robot_mode`` (§7.1); libfranka's ``franka::RobotMode`` uses the same numbers."""

    kOther = 0
    kIdle = 1
    kMove = 2
    kGuiding = 3
    kReflex = 4
    kUserStopped = 5
    kAutomaticErrorRecovery = 6


class MotionGeneratorMode(IntEnum):
    """State ``motion_generator_mode`` (§7.1). One more than the Move request value (§5.2)."""

    kIdle = 0
    kJointPosition = 1
    kJointVelocity = 2
    kCartesianPosition = 3
    kCartesianVelocity = 4
    kNone = 5  # torque-only motion


class ControllerMode(IntEnum):
    """State ``controller_mode`` (§7.1)."""

    kJointImpedance = 0
    kCartesianImpedance = 1
    kExternalController = 2
    kOther = 3


class MoveControllerMode(IntEnum):
    """Move request ``controller_mode`` (§5.1); same numbers as the state enum (§5.2)."""

    kJointImpedance = 0
    kCartesianImpedance = 1
    kExternalController = 2


class MoveMotionGeneratorMode(IntEnum):
    """Move request ``motion_generator_mode`` (§5.1); off by one from the state enum (§5.2)."""

    kJointPosition = 0
    kJointVelocity = 1
    kCartesianPosition = 2
    kCartesianVelocity = 3
    kNone = 4


def state_motion_generator_mode(move_mode: int) -> MotionGeneratorMode:
    """Map a Move request's motion-generator mode to the value the state publishes (§5.2).

    Raises ``ValueError`` for a value outside ``MoveMotionGeneratorMode``.
    """
    return MotionGeneratorMode(MoveMotionGeneratorMode(move_mode) + 1)


def state_controller_mode(move_mode: int) -> ControllerMode:
    """Map a Move request's controller mode to the state's value (§5.2: same numbers).

    Raises ``ValueError`` for a value outside ``MoveControllerMode``.
    """
    return ControllerMode(int(MoveControllerMode(move_mode)))
