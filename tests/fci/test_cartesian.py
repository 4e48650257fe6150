"""The Cartesian generators in-process: driven through IK, the three regimes of the commanded
fields, every row of the Cartesian tables of docs/motion-limits.md provoked to exactly its index,
the lost-cycle laws, and the calibration replay (docs/fci-behaviour.md "Calibration on an FER"; "The
joint side of a Cartesian command")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.errors import ERROR_NAMES, Error, error_names
from franka_sim_gym.fci.protocol import MoveStatus
from franka_sim_gym.fci.wire import MoveMotionGeneratorMode, RobotMode
from franka_sim_gym.sim.rotations import rotation_exp
from tests.fci_helpers import LoopClient, make_controller

CP = MoveMotionGeneratorMode.kCartesianPosition
CV = MoveMotionGeneratorMode.kCartesianVelocity
DT = 1e-3


def start(generator, **config) -> LoopClient:
    ctrl = make_controller(**config)
    client = LoopClient(ctrl)
    assert client.start(generator) == MoveStatus.kMotionStarted
    return client


def pose0(client: LoopClient) -> np.ndarray:
    """The pose a libfranka pose generator starts from: state.O_T_EE_d, as float64."""
    return np.array(client.state["O_T_EE_d"], dtype=np.float64)


def errors(client: LoopClient) -> tuple[str, ...]:
    return error_names(client.state["errors"])


def ramp_x(client: LoopClient, T0, v_max, a_max, j_max, cycles):
    """A +x pose ramp by a jerk-limited profile (libfranka limitRate-style budgets);
    returns the cycle (1-based) of the first abort, or None."""
    T, v, a = T0.copy(), 0.0, 0.0
    for k in range(1, cycles + 1):
        # Brake the acceleration at the jerk budget in time to meet v_max without a step.
        if v + a * a / (2.0 * j_max) >= v_max - 1e-12:
            a = max(a - j_max * DT, 0.0)
        else:
            a = min(a + j_max * DT, a_max)
        v = min(v + a * DT, v_max)
        T = T.copy()
        T[12] += v * DT
        client.send(O_T_EE_c=T)
        if client.state["robot_mode"] != RobotMode.kMove:
            return k
    return None


def accelerate_x(client: LoopClient, a: float, cycles: int) -> None:
    """From rest at the start pose, accelerate along +x at ``a`` [m/s^2] at once."""
    T = pose0(client)
    client.send(O_T_EE_c=T)
    v = 0.0
    for _ in range(cycles):
        v += a * DT
        T = T.copy()
        T[12] += v * DT
        client.send(O_T_EE_c=T)


# -- driving the arm ---------------------------------------------------------------------------


def test_cartesian_pose_motion_moves_the_arm_to_the_commanded_pose():
    c = start(CP, enforce_motion_limits=True)
    T0 = pose0(c)
    x0 = T0[12]
    for k in range(1500):
        T = T0.copy()
        T[12] = x0 + 0.05 * (1 - math.cos(math.pi * k / 1499)) / 2
        c.send(O_T_EE_c=T)
        if k == 700:  # mid-motion: O_T_EE_d / O_T_EE_c echo the commanded pose, q_d is q
            np.testing.assert_allclose(c.state["O_T_EE_c"], T.astype(np.float32))
            np.testing.assert_allclose(c.state["O_T_EE_d"], T.astype(np.float32))
            np.testing.assert_array_equal(c.state["q_d"], c.state["q"])
    assert c.finish(O_T_EE_c=T) == MoveStatus.kSuccess
    c.idle(300)
    assert c.state["O_T_EE"][12] == pytest.approx(x0 + 0.05, abs=1e-4)
    assert c.state["O_T_EE"][13] == pytest.approx(T0[13], abs=1e-4)
    assert not c.ctrl.violations.seen.any()


def test_cartesian_velocity_motion_moves_the_arm_by_the_twist_integral():
    """A 5 cm twist integral arrives within 2 mm (docs/fci-behaviour.md "RobotState fields": not 39
    % of it)."""
    c = start(CV, enforce_motion_limits=True)
    x0 = float(c.state["O_T_EE"][12])
    start_pose = np.array(c.state["O_T_EE_d"])
    duration = 2.0
    n = int(duration / DT)
    for k in range(n):
        t = k * DT
        # v(t) = 0.05 * pi / (2 T) sin(pi t / T): integral over T is 5 cm.
        v = 0.05 * math.pi / (2 * duration) * math.sin(math.pi * t / duration)
        c.send(O_dP_EE_c=[v, 0, 0, 0, 0, 0])
        if k == n // 2:
            # O_dP_EE_c / O_dP_EE_d echo the twist; O_T_EE_d is frozen at the start pose.
            assert c.state["O_dP_EE_c"][0] == pytest.approx(v, rel=1e-6)
            assert c.state["O_dP_EE_d"][0] == pytest.approx(v, rel=1e-6)
            np.testing.assert_array_equal(c.state["O_T_EE_d"], start_pose)
            np.testing.assert_array_equal(c.state["O_T_EE_c"], start_pose)
    assert c.finish(O_dP_EE_c=np.zeros(6)) == MoveStatus.kSuccess
    c.idle(300)
    assert float(c.state["O_T_EE"][12]) - x0 == pytest.approx(0.05, abs=2e-3)
    # After the motion: O_T_EE_d back to measured, the twist echo back to zero.
    np.testing.assert_array_equal(c.state["O_T_EE_d"], c.state["O_T_EE"])
    assert not c.state["O_dP_EE_c"].any()
    assert not c.ctrl.violations.seen.any()


def test_a_pose_motion_reports_its_commanded_twist_and_acceleration():
    """O_dP_EE_c / O_dP_EE_d carry the commanded pose's twist (base frame) and O_ddP_EE_c
    its rate: libfranka's pose rate limiter reads them back as the last commanded twist and
    acceleration (with zeros there a limit_rate client could never leave a crawl)."""
    c = start(CP, enforce_motion_limits=True)
    T0 = frames.from_wire(pose0(c)[None])[0]
    c.send(O_T_EE_c=frames.to_wire(T0[None])[0])
    axis = np.array([0.0, 0.6, 0.8])
    for k in range(1, 200):
        v, w = 0.2 * k * DT, 0.5 * k * DT  # ramps at 0.2 m/s^2, 0.5 rad/s^2
        T = T0.copy()
        T[0, 3] += 0.5 * 0.2 * (k * DT) ** 2 + 0.5 * 0.2 * k * DT * DT  # sum of v DT
        theta = 0.25 * DT * DT * k * (k + 1)  # sum of w DT: 0.5 DT^2 (1 + ... + k)
        T[:3, :3] = rotation_exp(theta * axis) @ T0[:3, :3]
        c.send(O_T_EE_c=frames.to_wire(T[None])[0])
        assert c.state["robot_mode"] == RobotMode.kMove, errors(c)
        if k > 2:
            np.testing.assert_allclose(c.state["O_dP_EE_c"][:3], [v, 0, 0], atol=1e-5)
            np.testing.assert_allclose(c.state["O_dP_EE_c"][3:], w * axis, atol=1e-5)
            np.testing.assert_array_equal(c.state["O_dP_EE_d"], c.state["O_dP_EE_c"])
            np.testing.assert_allclose(c.state["O_ddP_EE_c"][:3], [0.2, 0, 0], atol=2e-3)
            np.testing.assert_allclose(c.state["O_ddP_EE_c"][3:], 0.5 * axis, atol=2e-3)
    # Repeating the last pose stops it dead from 0.04 m/s: a 40 m/s^2 step (19), aborted.
    assert c.finish(O_T_EE_c=frames.to_wire(T[None])[0]) == MoveStatus.kReflexAborted
    assert errors(c) == ("cartesian_motion_generator_velocity_discontinuity",)
    c.idle(5)
    assert c.state["robot_mode"] != RobotMode.kMove
    assert not c.state["O_dP_EE_c"].any() and not c.state["O_ddP_EE_c"].any()


def test_cartesian_pose_with_elbow_holds_joint_3_at_the_commanded_elbow():
    c = start(CP, enforce_motion_limits=True)
    T0 = pose0(c)
    elbow0 = np.array(c.state["elbow_d"], dtype=np.float64)
    for k in range(1000):
        e = elbow0.copy()
        e[0] += 0.1 * (1 - math.cos(math.pi * k / 999)) / 2
        c.send(O_T_EE_c=T0, elbow_c=e, valid_elbow=True)
        if k == 500:
            np.testing.assert_allclose(c.state["elbow_c"], e.astype(np.float32))
    assert c.finish(O_T_EE_c=T0, elbow_c=e, valid_elbow=True) == MoveStatus.kSuccess
    c.idle(300)
    assert float(c.state["q"][2]) == pytest.approx(elbow0[0] + 0.1, abs=1e-3)
    np.testing.assert_allclose(c.state["O_T_EE"][12:15], T0[12:15], atol=2e-4)
    # The motion over, elbow_d / elbow_c read the measured elbow again.
    np.testing.assert_array_equal(c.state["elbow_c"], c.state["elbow"])


def test_cartesian_pose_follows_a_tool_frame_set_with_set_ne_to_ee():
    ctrl = make_controller(enforce_motion_limits=True)
    tool = np.eye(4)
    tool[2, 3] = 0.2
    ctrl.set_ne_to_ee(0, frames.to_wire(tool))
    c = LoopClient(ctrl)
    c.idle(2)
    c.start(CP)
    T0 = pose0(c)
    for k in range(800):
        T = T0.copy()
        T[14] -= 0.03 * (1 - math.cos(math.pi * k / 799)) / 2
        c.send(O_T_EE_c=T)
    assert c.finish(O_T_EE_c=T) == MoveStatus.kSuccess
    c.idle(300)
    assert float(c.state["O_T_EE"][14]) == pytest.approx(T0[14] - 0.03, abs=1e-4)


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


# -- lost cycles --------------------------------------------------------------------------------


def test_lost_cycles_of_a_constant_acceleration_pose_stream_are_extrapolated_onto_it():
    """docs/fci-behaviour.md "The real-robot trap you can now reproduce": a stream whose
    acceleration is constant is extrapolated onto its own next
    waypoints; resuming after a gap trips nothing."""
    c = start(CP, enforce_motion_limits=True)
    T0 = pose0(c)
    x = lambda k: T0[12] + 0.5 * 0.5 * (k * DT) ** 2  # noqa: E731 - 0.5 m/s^2 along x
    for k in range(60):
        T = T0.copy()
        T[12] = x(k)
        c.send(deliver=not (30 <= k < 40), O_T_EE_c=T)
        if k == 39:  # ten cycles extrapolated: the published pose is the stream's own
            assert float(c.state["O_T_EE_c"][12]) == pytest.approx(x(39), abs=1e-7)
    assert errors(c) == ()
    assert c.state["robot_mode"] == RobotMode.kMove


def test_twist_is_held_through_lost_cycles_and_stops_after_20():
    c = start(CV, enforce_motion_limits=True)
    for k in range(51):  # from rest, 1 m/s^2 up to 0.01 m/s, then constant
        c.send(O_dP_EE_c=[min(k, 10) * 1e-3, 0, 0, 0, 0, 0])
    for _ in range(5):
        c.send(deliver=False)
    assert c.state["O_dP_EE_c"][0] == pytest.approx(0.01)  # frozen acceleration: zero
    for _ in range(20):
        c.send(deliver=False)
    assert c.state["O_dP_EE_c"][0] == 0.0  # past the bound the arm stands still


# -- the calibration replay (docs/fci-behaviour.md "Calibration on an FER") ------------------------

CALIBRATION_Q = [-0.046, -0.873, -0.104, -2.437, -0.051, 1.617, 0.748]


def _calibration(robot: str) -> LoopClient:
    """The FER calibration set-up (docs/fci-behaviour.md "Calibration on an FER"): start q, the
    Franka Hand's F_T_EE
    (Rz(45 deg), 0.1034 m), 0.5 s at rest before the ramp."""
    ctrl = make_controller(robot=robot, enforce_motion_limits=True)
    ctrl.reset([0], np.array([CALIBRATION_Q]))
    hand = np.eye(4)
    c45 = math.cos(math.pi / 4)
    hand[:3, :3] = [[c45, -c45, 0], [c45, c45, 0], [0, 0, 1]]
    hand[2, 3] = 0.1034
    ctrl.set_ne_to_ee(0, frames.to_wire(hand))
    c = LoopClient(ctrl)
    c.idle(5)
    c.start(CP)
    T0 = pose0(c)
    for _ in range(500):
        c.send(O_T_EE_c=T0)
    return c


# libfranka 0.9 rate_limiting.h FER budgets are the robot's limits minus kLimitEps.
@pytest.mark.parametrize(
    "v, a, j, trip, names",
    [
        (1.7 - 1e-3, 13.0 - 1e-3, 6500.0 - 1e-3, "early", {29, 30}),
        (0.5, 2.5, 500.0, 5, {29}),
        (0.3, 2.5, 500.0, 5, {29}),
        (0.3, 1.5, 200.0, None, set()),
        (0.4, 1.0, 100.0, None, set()),
        (0.3, 0.5, 20.0, None, set()),
    ],
)
def test_fer_calibration_replay(v, a, j, trip, names):
    """docs/fci-behaviour.md "Calibration on an FER": the 13 m/s^2 ramp refused within the first
    cycles
    with 29 and 30; the 2.5 m/s^2 ramp refused with 29 alone on the cycle where the
    per-cycle velocity increment reaches 2.5 mm/s (steps 0.5, 1.5, 3, 5, 7.5 um); the
    1.5 m/s^2 and slower ramps pass."""
    c = _calibration("fer")
    k = ramp_x(c, pose0(c), v, a, j, 500)
    if trip is None:
        assert k is None and errors(c) == ()
    elif trip == "early":
        assert k is not None and k <= 3
    else:
        assert k == trip
    assert {int(Error[name]) for name in errors(c)} == names


@pytest.mark.parametrize("a, refused", [(2.5, False), (3.5, True)])
def test_fr3_calibration_2_5_passes_and_3_5_is_refused(a, refused):
    c = _calibration("fr3")
    k = ramp_x(c, pose0(c), 0.5, a, 500.0, 500)
    assert (k is not None) == refused
    assert errors(c) == (
        ("cartesian_motion_generator_joint_velocity_discontinuity",) if refused else ()
    )


def test_an_unreachable_pose_holds_the_arm_at_its_last_usable_solution(caplog):
    """A resumed stream 1 m off (what a stalled client sends with enforcement off): the
    IK cannot converge; the servo holds the last usable solution instead of following a
    diverging iterate into the stops, and the arm comes back when the pose does."""
    c = start(CP, enforce_motion_limits=False)
    T0 = pose0(c)
    c.send(O_T_EE_c=T0)
    held = c.ctrl.cartesian.q_ik[0].copy()
    far = T0.copy()
    far[12] += 1.0
    far[14] -= 1.0
    with caplog.at_level("WARNING"):
        for _ in range(300):
            c.send(O_T_EE_c=far)
    assert "no converged IK solution" in caplog.text
    assert c.state["robot_mode"] == RobotMode.kMove
    np.testing.assert_array_equal(c.ctrl.cartesian.q_ik[0], held)
    assert np.abs(c.state["dq"]).max() < 1e-2  # at rest, not flailing
    np.testing.assert_allclose(c.state["q"], held, atol=2e-3)
    for _ in range(500):
        c.send(O_T_EE_c=T0)
    np.testing.assert_allclose(c.state["O_T_EE"][12:15], T0[12:15], atol=1e-3)
