"""Every row of the Cartesian tables of docs/motion-limits.md provoked to exactly its index,
in-process (31, 16, 22, 21, 19, 18, 20, 29, 30, 17; twist 20, 18, 30, 21, 17; docs/fci-behaviour.md
"The joint side of a Cartesian command")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.errors import ERROR_NAMES, Error
from franka_sim_gym.fci.wire import RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from tests.cartesian_helpers import CP, CV, DT, accelerate_x, errors, pose0, ramp_x, start

# -- every row, provoked to exactly its index ---------------------------------------------------


def test_invalid_frame_31_is_refused_even_with_enforcement_off():
    c = start(CP)  # enforcement off
    T0 = pose0(c)
    bad = T0.copy()
    bad[0] *= 1.1  # the rotation block is no longer orthonormal
    c.send(O_T_EE_c=T0)
    c.send(O_T_EE_c=bad)
    assert c.ctrl.violations.seen[0, Error.cartesian_position_motion_generator_invalid_frame]
    assert c.state["robot_mode"] == RobotMode.kMove  # logged, not aborted
    c = start(CP, enforce_motion_limits=True)
    c.send(O_T_EE_c=pose0(c))
    c.send(O_T_EE_c=bad)
    assert errors(c) == (ERROR_NAMES[Error.cartesian_position_motion_generator_invalid_frame],)
    assert c.move_statuses() == [MoveStatus.kReflexAborted]


def test_first_pose_15_cm_off_is_start_pose_invalid_16():
    c = start(CP, enforce_motion_limits=True)
    T = pose0(c)
    T[12] += 0.15
    c.send(O_T_EE_c=T)
    assert errors(c) == ("cartesian_position_motion_generator_start_pose_invalid",)


def test_first_pose_rotated_over_0_1_rad_is_16_and_just_inside_passes():
    for angle, expected in (
        (0.12, ("cartesian_position_motion_generator_start_pose_invalid",)),
        (0.0, ()),
    ):
        c = start(CP, enforce_motion_limits=True)
        T = frames.from_wire(pose0(c))
        ca, sa = math.cos(angle), math.sin(angle)
        T[:3, :3] = T[:3, :3] @ np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
        c.send(O_T_EE_c=frames.to_wire(T))
        assert errors(c) == expected


@pytest.mark.parametrize("offset, flag", [(0.2, None), (0.0, 1.0)])
def test_first_elbow_off_or_of_the_wrong_sign_is_start_elbow_invalid_22(offset, flag):
    c = start(CP, enforce_motion_limits=True)
    e = np.array(c.state["elbow"], dtype=np.float64)
    e[0] += offset
    if flag is not None:
        e[1] = flag  # the measured flag is -1 (joint 4 is always negative on an FR3)
    c.send(O_T_EE_c=pose0(c), elbow_c=e, valid_elbow=True)
    assert errors(c) == ("cartesian_motion_generator_start_elbow_invalid",)


@pytest.mark.parametrize("generator", [CP, CV])
def test_elbow_flag_flip_mid_motion_is_21(generator):
    c = start(generator, enforce_motion_limits=True)
    e = np.array(c.state["elbow"], dtype=np.float64)
    fields = {"O_T_EE_c": pose0(c)} if generator == CP else {"O_dP_EE_c": np.zeros(6)}
    c.send(elbow_c=e, valid_elbow=True, **fields)
    c.send(elbow_c=e, valid_elbow=True, **fields)
    c.send(elbow_c=[e[0], -e[1]], valid_elbow=True, **fields)
    assert errors(c) == ("cartesian_motion_generator_elbow_sign_inconsistent",)


def test_pose_step_is_velocity_discontinuity_19_not_18():
    c = start(CP, enforce_motion_limits=True)
    T = pose0(c)
    c.send(O_T_EE_c=T)
    T = T.copy()
    T[12] += 0.005  # 5 m/s in one cycle: breaks 19, 18 and 20; 19 is the name
    c.send(O_T_EE_c=T)
    assert errors(c) == ("cartesian_motion_generator_velocity_discontinuity",)


def test_pose_acceleration_step_is_acceleration_discontinuity_20():
    """a: 0 -> 6 m/s^2 in one cycle: jerk 6000 > 4500 (and the joint side trips too,
    later in precedence)."""
    c = start(CP, enforce_motion_limits=True)
    accelerate_x(c, 6.0, 2)
    assert errors(c) == ("cartesian_motion_generator_acceleration_discontinuity",)


def _spin(client, generator, alpha_max, jerk, omega_max, cycles):
    """Rotate about the flange z axis (joint 7's axis at home: no EE translation)."""
    T0 = frames.from_wire(pose0(client))
    angle = omega = alpha = 0.0
    # libfranka's loop opens with the start pose (time 0): at rest.
    if generator == CP:
        client.send(O_T_EE_c=pose0(client))
    else:
        client.send(O_dP_EE_c=np.zeros(6))
    for _ in range(cycles):
        if omega + alpha * alpha / (2.0 * jerk) >= omega_max:  # brake the acceleration
            alpha = max(alpha - jerk * DT, 0.0)
        else:
            alpha = min(alpha + jerk * DT, alpha_max)
        omega += alpha * DT
        angle += omega * DT
        if generator == CP:
            T = T0.copy()
            ca, sa = math.cos(angle), math.sin(angle)
            T[:3, :3] = T0[:3, :3] @ np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
            client.send(O_T_EE_c=frames.to_wire(T))
        else:
            axis = T0[:3, 2]  # the flange z axis in the base frame
            client.send(O_dP_EE_c=np.concatenate([np.zeros(3), omega * axis]))
        if client.state["robot_mode"] != RobotMode.kMove:
            return


@pytest.mark.parametrize("generator", [CP, CV])
def test_rotation_faster_than_2_5_rad_s_is_velocity_limits_violation_18(generator):
    """Smoothly too fast: 18. (The joint side is scaled out of the way: joint 7 alone
    turns, at up to 15 rad/s^2.)"""
    c = start(generator, enforce_motion_limits=True, joint_discontinuity_scale=2.0)
    _spin(c, generator, alpha_max=15.0, jerk=4000.0, omega_max=2.6, cycles=400)
    assert errors(c) == ("cartesian_motion_generator_velocity_limits_violation",)


@pytest.mark.parametrize("generator", [CP, CV])
def test_same_rotation_just_inside_2_5_rad_s_passes(generator):
    c = start(generator, enforce_motion_limits=True, joint_discontinuity_scale=2.0)
    _spin(c, generator, alpha_max=15.0, jerk=4000.0, omega_max=2.4, cycles=400)
    assert errors(c) == ()
    assert c.state["robot_mode"] == RobotMode.kMove


def test_ik_joint_acceleration_is_29_alone_for_a_3_5_m_s2_ramp_on_an_fr3():
    c = start(CP, enforce_motion_limits=True)
    c.send(O_T_EE_c=pose0(c))
    assert ramp_x(c, pose0(c), 0.5, 3.5, 500.0, 400) is not None
    assert errors(c) == ("cartesian_motion_generator_joint_velocity_discontinuity",)


def test_ik_joint_jerk_is_30_alone():
    """a: 0 -> 2 m/s^2 in one cycle: Cartesian jerk 2000 (< 4500), the joint side's
    acceleration ~6.5 rad/s^2 (< 10) but its jerk ~6500 rad/s^3 (> 5000)."""
    c = start(CP, enforce_motion_limits=True)
    accelerate_x(c, 2.0, 3)
    assert errors(c) == ("cartesian_motion_generator_joint_acceleration_discontinuity",)


def test_joint_discontinuity_scale_makes_the_joint_side_stricter():
    c = start(CP, enforce_motion_limits=True, joint_discontinuity_scale=0.5)
    c.send(O_T_EE_c=pose0(c))
    assert ramp_x(c, pose0(c), 0.5, 2.5, 500.0, 400) is not None
    assert "cartesian_motion_generator_joint_velocity_discontinuity" in errors(c)


@pytest.mark.parametrize("generator", [CP, CV])
def test_elbow_too_fast_is_elbow_limit_violation_17(generator):
    c = start(generator, enforce_motion_limits=True)
    e = np.array(c.state["elbow"], dtype=np.float64)
    fields = {"O_T_EE_c": pose0(c)} if generator == CP else {"O_dP_EE_c": np.zeros(6)}
    c.send(elbow_c=e, valid_elbow=True, **fields)  # opening at the measured elbow
    v = a = 0.0
    for _ in range(400):
        a = min(a + 2000.0 * DT, 5.0)
        v += a * DT
        e = e.copy()
        e[0] += v * DT
        c.send(elbow_c=e, valid_elbow=True, **fields)
        if c.state["robot_mode"] != RobotMode.kMove:
            break
    assert errors(c) == ("cartesian_motion_generator_elbow_limit_violation",)


def test_twist_step_is_acceleration_discontinuity_20():
    c = start(CV, enforce_motion_limits=True)
    c.send(O_dP_EE_c=np.zeros(6))
    c.send(O_dP_EE_c=[0.1, 0, 0, 0, 0, 0])  # 100 m/s^2
    assert errors(c) == ("cartesian_motion_generator_acceleration_discontinuity",)


def test_twist_ramp_at_3_5_m_s2_trips_the_joint_side_30():
    c = start(CV, enforce_motion_limits=True)
    c.send(O_dP_EE_c=np.zeros(6))
    v = a = 0.0
    for _ in range(300):
        a = min(a + 500.0 * DT, 3.5)
        v += a * DT
        c.send(O_dP_EE_c=[v, 0, 0, 0, 0, 0])
        if c.state["robot_mode"] != RobotMode.kMove:
            break
    assert errors(c) == ("cartesian_motion_generator_joint_acceleration_discontinuity",)


def test_non_finite_twist_is_refused_as_18_whatever_the_enforcement():
    c = start(CV)
    c.send(O_dP_EE_c=[np.nan, 0, 0, 0, 0, 0])
    assert c.ctrl.violations.seen[0, Error.cartesian_motion_generator_velocity_limits_violation]
    assert c.state["robot_mode"] == RobotMode.kMove
    assert np.isfinite(c.state["O_dP_EE_c"]).all()
