"""The robot server v10's wire: the UDP layouts as numpy structured dtypes and the mode
enums (layouts.py, re-exported here: ``franka_sim_gym.fci.wire.ROBOT_STATE_DTYPE``), the
TCP messages (protocol.py), their framing (fci/wire/framing.py), the requests' payloads
(fci/wire/request_payloads.py) and the command ids and reply statuses (fci/wire/statuses.py);
docs/wire-protocol.md byte for byte."""

from .layouts import (
    GRIPPER_STATE_DTYPE,
    GRIPPER_STATE_SIZE,
    ROBOT_COMMAND_DTYPE,
    ROBOT_COMMAND_SIZE,
    ROBOT_STATE_DTYPE,
    ROBOT_STATE_SIZE,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
    state_controller_mode,
    state_motion_generator_mode,
)

__all__ = [
    "GRIPPER_STATE_DTYPE",
    "GRIPPER_STATE_SIZE",
    "ROBOT_COMMAND_DTYPE",
    "ROBOT_COMMAND_SIZE",
    "ROBOT_STATE_DTYPE",
    "ROBOT_STATE_SIZE",
    "ControllerMode",
    "MotionGeneratorMode",
    "MoveControllerMode",
    "MoveMotionGeneratorMode",
    "RobotMode",
    "state_controller_mode",
    "state_motion_generator_mode",
]
