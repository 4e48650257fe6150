"""The Cartesian generators in-process: driven through IK (pose, twist, elbow, a tool
frame), the three regimes of the commanded fields, the lost-cycle laws, and an unreachable
pose held at its last usable solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.wire import RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from franka_sim_gym.sim.rotations import rotation_exp
from tests.cartesian_helpers import CP, CV, DT, errors, pose0, start
from tests.fci_helpers import LoopClient, make_controller

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
