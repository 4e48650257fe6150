"""The wire dtypes match the byte tables of docs/wire-protocol.md §7, §8, §10.3 exactly."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.wire import (
    GRIPPER_STATE_DTYPE,
    ROBOT_COMMAND_DTYPE,
    ROBOT_STATE_DTYPE,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
    state_controller_mode,
    state_motion_generator_mode,
)

# Transcribed from the §7 table: (field, offset, bytes).
ROBOT_STATE_TABLE = [
    ("message_id", 0, 8),
    ("O_T_EE", 8, 64),
    ("O_T_EE_d", 72, 64),
    ("F_T_EE", 136, 64),
    ("EE_T_K", 200, 64),
    ("F_T_NE", 264, 64),
    ("NE_T_EE", 328, 64),
    ("m_ee", 392, 4),
    ("I_ee", 396, 36),
    ("F_x_Cee", 432, 12),
    ("m_load", 444, 4),
    ("I_load", 448, 36),
    ("F_x_Cload", 484, 12),
    ("elbow", 496, 8),
    ("elbow_d", 504, 8),
    ("tau_J", 512, 28),
    ("tau_J_d", 540, 28),
    ("dtau_J", 568, 28),
    ("q", 596, 28),
    ("q_d", 624, 28),
    ("dq", 652, 28),
    ("dq_d", 680, 28),
    ("ddq_d", 708, 28),
    ("joint_contact", 736, 28),
    ("cartesian_contact", 764, 24),
    ("joint_collision", 788, 28),
    ("cartesian_collision", 816, 24),
    ("tau_ext_hat_filtered", 840, 28),
    ("O_F_ext_hat_K", 868, 24),
    ("K_F_ext_hat_K", 892, 24),
    ("O_dP_EE_d", 916, 24),
    ("O_ddP_O", 940, 12),
    ("elbow_c", 952, 8),
    ("delbow_c", 960, 8),
    ("ddelbow_c", 968, 8),
    ("O_T_EE_c", 976, 64),
    ("O_dP_EE_c", 1040, 24),
    ("O_ddP_EE_c", 1064, 24),
    ("theta", 1088, 28),
    ("dtheta", 1116, 28),
    ("accelerometer_top", 1144, 72),
    ("accelerometer_bottom", 1216, 72),
    ("motion_generator_mode", 1288, 1),
    ("controller_mode", 1289, 1),
    ("errors", 1290, 41),
    ("reflex_reason", 1331, 41),
    ("robot_mode", 1372, 1),
    ("control_command_success_rate", 1373, 4),
]

# §8 (motion.* / control.* flattened).
ROBOT_COMMAND_TABLE = [
    ("message_id", 0, 8),
    ("q_c", 8, 56),
    ("dq_c", 64, 56),
    ("O_T_EE_c", 120, 128),
    ("O_dP_EE_c", 248, 48),
    ("elbow_c", 296, 16),
    ("valid_elbow", 312, 1),
    ("motion_generation_finished", 313, 1),
    ("tau_J_d", 314, 56),
    ("torque_command_finished", 370, 1),
]

# §10.3.
GRIPPER_STATE_TABLE = [
    ("message_id", 0, 4),
    ("width", 4, 8),
    ("max_width", 12, 8),
    ("is_grasped", 20, 1),
    ("temperature", 21, 2),
]


def _layout(dtype: np.dtype) -> list[tuple[str, int, int]]:
    return [(name, dtype.fields[name][1], dtype.fields[name][0].itemsize) for name in dtype.names]


def test_itemsizes_are_the_datagram_sizes():
    assert ROBOT_STATE_DTYPE.itemsize == 1377
    assert ROBOT_COMMAND_DTYPE.itemsize == 371
    assert GRIPPER_STATE_DTYPE.itemsize == 23


@pytest.mark.parametrize(
    ("dtype", "table"),
    [
        (ROBOT_STATE_DTYPE, ROBOT_STATE_TABLE),
        (ROBOT_COMMAND_DTYPE, ROBOT_COMMAND_TABLE),
        (GRIPPER_STATE_DTYPE, GRIPPER_STATE_TABLE),
    ],
    ids=["RobotState", "RobotCommand", "GripperState"],
)
def test_every_field_has_the_spec_offset_and_size_in_order(dtype, table):
    assert _layout(dtype) == table


def test_tables_tile_the_datagram_without_gaps():
    # Sanity of the transcription itself: each field starts where the last ended.
    for table, total in (
        (ROBOT_STATE_TABLE, 1377),
        (ROBOT_COMMAND_TABLE, 371),
        (GRIPPER_STATE_TABLE, 23),
    ):
        end = 0
        for name, offset, size in table:
            assert offset == end, name
            end = offset + size
        assert end == total


def test_state_floats_are_little_endian_f32_and_commands_f64():
    for name in ROBOT_STATE_DTYPE.names:
        base = ROBOT_STATE_DTYPE.fields[name][0].base
        if base.kind == "f":
            assert base.str == "<f4", name
    for name in ("q_c", "dq_c", "O_T_EE_c", "O_dP_EE_c", "elbow_c", "tau_J_d"):
        assert ROBOT_COMMAND_DTYPE.fields[name][0].base.str == "<f8", name
    assert ROBOT_STATE_DTYPE.fields["message_id"][0].str == "<u8"
    assert GRIPPER_STATE_DTYPE.fields["temperature"][0].str == "<u2"


def test_accelerometer_element_i_k_sits_at_1144_plus_12i_plus_4k():
    state = np.zeros((), dtype=ROBOT_STATE_DTYPE)
    top = np.arange(18, dtype=np.float32).reshape(6, 3) + 1.0
    state["accelerometer_top"] = top
    raw = state.tobytes()
    for i in range(6):
        for k in range(3):
            offset = 1144 + 12 * i + 4 * k
            assert np.frombuffer(raw, "<f4", count=1, offset=offset)[0] == top[i, k]
    bottom_first = np.frombuffer(raw, "<f4", count=1, offset=1216)[0]
    assert bottom_first == 0.0


def test_filled_state_round_trips_through_bytes_little_endian():
    rng = np.random.default_rng(7)
    state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
    for name in ROBOT_STATE_DTYPE.names:
        field = state[name]
        if field.dtype.kind == "f":
            field[...] = rng.standard_normal(field.shape)
        elif field.dtype.kind == "b":
            field[...] = rng.random(field.shape) < 0.5
    state["message_id"] = 0x0102030405060708
    state["robot_mode"] = RobotMode.kReflex
    state["motion_generator_mode"] = MotionGeneratorMode.kNone
    state["controller_mode"] = ControllerMode.kExternalController
    state["control_command_success_rate"] = 0.5
    raw = state[0].tobytes()
    assert len(raw) == 1377
    assert raw[0:8] == bytes([8, 7, 6, 5, 4, 3, 2, 1])  # little-endian u64
    assert raw[1288] == 5 and raw[1289] == 2 and raw[1372] == 4
    assert raw[1373:1377] == np.float32(0.5).tobytes() == b"\x00\x00\x00\x3f"
    assert raw[1290:1331] == state[0]["errors"].astype(np.uint8).tobytes()
    back = np.frombuffer(raw, dtype=ROBOT_STATE_DTYPE)[0]
    assert back.tobytes() == raw
    for name in ROBOT_STATE_DTYPE.names:
        np.testing.assert_array_equal(back[name], state[0][name], err_msg=name)


def test_command_bytes_decode_into_fields():
    cmd = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
    cmd["message_id"] = 42
    cmd["q_c"] = np.arange(7) * 0.1
    cmd["valid_elbow"] = True
    cmd["torque_command_finished"] = True
    raw = cmd.tobytes()
    assert raw[312] == 1 and raw[313] == 0 and raw[370] == 1
    assert np.frombuffer(raw, "<f8", count=7, offset=8).tolist() == (np.arange(7) * 0.1).tolist()
    back = np.frombuffer(raw, dtype=ROBOT_COMMAND_DTYPE)[0]
    assert back["message_id"] == 42 and bool(back["valid_elbow"])


def test_state_enums_have_the_robot_numbers():
    assert [(m.name, m.value) for m in RobotMode] == [
        ("kOther", 0),
        ("kIdle", 1),
        ("kMove", 2),
        ("kGuiding", 3),
        ("kReflex", 4),
        ("kUserStopped", 5),
        ("kAutomaticErrorRecovery", 6),
    ]
    assert [(m.name, m.value) for m in MotionGeneratorMode] == [
        ("kIdle", 0),
        ("kJointPosition", 1),
        ("kJointVelocity", 2),
        ("kCartesianPosition", 3),
        ("kCartesianVelocity", 4),
        ("kNone", 5),
    ]
    assert [(m.name, m.value) for m in ControllerMode] == [
        ("kJointImpedance", 0),
        ("kCartesianImpedance", 1),
        ("kExternalController", 2),
        ("kOther", 3),
    ]
    assert [(m.name, m.value) for m in MoveControllerMode] == [
        ("kJointImpedance", 0),
        ("kCartesianImpedance", 1),
        ("kExternalController", 2),
    ]
    assert [(m.name, m.value) for m in MoveMotionGeneratorMode] == [
        ("kJointPosition", 0),
        ("kJointVelocity", 1),
        ("kCartesianPosition", 2),
        ("kCartesianVelocity", 3),
        ("kNone", 4),
    ]


def test_move_motion_generator_mode_maps_off_by_one_to_state_mode():
    # §5.2 table, transcribed.
    expected = {
        0: MotionGeneratorMode.kJointPosition,
        1: MotionGeneratorMode.kJointVelocity,
        2: MotionGeneratorMode.kCartesianPosition,
        3: MotionGeneratorMode.kCartesianVelocity,
        4: MotionGeneratorMode.kNone,
    }
    for move_mode, state_mode in expected.items():
        assert state_motion_generator_mode(move_mode) is state_mode
    assert state_motion_generator_mode(MoveMotionGeneratorMode.kNone) == 5


@pytest.mark.parametrize("bad", [-1, 5, 99])
def test_move_motion_generator_mode_outside_enum_is_rejected(bad):
    with pytest.raises(ValueError):
        state_motion_generator_mode(bad)


def test_move_controller_mode_maps_to_the_same_state_number():
    assert state_controller_mode(0) is ControllerMode.kJointImpedance
    assert state_controller_mode(1) is ControllerMode.kCartesianImpedance
    assert state_controller_mode(2) is ControllerMode.kExternalController
    with pytest.raises(ValueError):
        state_controller_mode(3)  # kOther exists only in the state enum
