"""The idle hold (fci/hold.py): every switch of the robot's controllers is continuous.

A press on the table under kCartesianImpedance (500 N/m, the pose 2 cm under the table:
10 N) is the probe: the force the table feels (MuJoCo's contact, the ground truth)
and what the robot reports must not move where no command moves them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.modes import CARTESIAN_IMPEDANCE, JOINT_IMPEDANCE
from franka_sim_gym.fci.wire import MoveControllerMode, MoveMotionGeneratorMode
from franka_sim_gym.fci.wire.statuses import MoveStatus
from tests.fci.contact.test_contact_sensing import thresholds
from tests.fci_helpers import EXT, IMP, JP, NONE, LoopClient, make_controller
from tests.sim.test_scene import OVER_THE_TABLE, table_contacts

CI = MoveControllerMode.kCartesianImpedance
POSE = MoveMotionGeneratorMode.kCartesianPosition


def pressed(servo=CI, depth: float = 0.02):
    """A finished pose motion under ``servo`` that pressed ``depth`` under the table
    (1 s down, held 0.3 s) at SetCartesianImpedance 500 N/m; the controller and client."""
    ctrl = make_controller(1, enforce_motion_limits=True)
    ctrl.reset([0], OVER_THE_TABLE[None])
    ctrl.set_collision_behavior(0, thresholds(force=(100.0, 100.0)))
    ctrl.set_cartesian_impedance(0, [500.0] * 3 + [150.0] * 3)
    client = LoopClient(ctrl)
    assert client.start(POSE, servo) == MoveStatus.kMotionStarted
    pose = client.state["O_T_EE_c"].astype(np.float64)
    z0 = pose[14]
    for k in range(1300):
        pose[14] = z0 - (z0 + depth) * 0.5 * (1 - math.cos(math.pi * min(k / 1000, 1.0)))
        client.send(O_T_EE_c=pose)
    assert client.finish(O_T_EE_c=pose) == MoveStatus.kSuccess
    return ctrl, client


def test_a_press_that_finished_is_held_by_its_own_servo_with_its_force():
    ctrl, client = pressed()
    force, _, _ = table_contacts(ctrl.physics)
    estimate = client.state["O_F_ext_hat_K"][2]
    assert force == pytest.approx(10.0, abs=1.0)
    # Idle now: the Cartesian servo holds, and says so (docs/robot-state.md).
    assert client.state["controller_mode"] == CARTESIAN_IMPEDANCE
    client.idle(500)
    assert table_contacts(ctrl.physics)[0] == pytest.approx(force, abs=0.1)
    assert client.state["O_F_ext_hat_K"][2] == pytest.approx(estimate, abs=0.1)


def test_a_move_changes_nothing_until_its_first_command():
    ctrl, client = pressed()
    tau = client.state["tau_J"].copy()
    # libfranka reads two states after the mode switch before its first command.
    assert client.start(NONE, EXT) == MoveStatus.kMotionStarted
    client.idle(3)
    np.testing.assert_allclose(client.state["tau_J"], tau, atol=1e-3)
    # The first command (zero torque) releases the press, by the press's torque.
    press = client.state["tau_ext_hat_filtered"].copy()
    client.send(tau_J_d=np.zeros(7))
    np.testing.assert_allclose(client.state["tau_J"], tau - press, atol=0.1)


@pytest.mark.parametrize(
    ("first", "then"),
    [(CI, IMP), (CI, CI), (IMP, CI), (IMP, IMP)],
    ids=["cartesian-joint", "cartesian-cartesian", "joint-cartesian", "joint-joint"],
)
def test_the_next_servo_takes_over_a_press_where_its_first_command_puts_it(first, then):
    """A press under one internal servo, then a motion under either, whose commands
    hold the measured q (a joint-position motion under JointImpedance) or the measured
    pose (a pose motion under CartesianImpedance), as libfranka's examples start: the
    press is released as the new servo takes over -- no reflex at the 100 N thresholds,
    no state reads more force than the press had."""
    ctrl, client = pressed(first, 0.02 if first == CI else 0.002)
    press = client.state["O_F_ext_hat_K"][2]
    client.idle(50)  # a client reading idle states, then starting the next motion
    generator = JP if then == IMP else POSE
    assert client.start(generator, then) == MoveStatus.kMotionStarted
    command = {"q_c": client.state["q"].copy()}
    if then == CI:
        command = {"O_T_EE_c": client.state["O_T_EE"].astype(np.float64)}
    worst = 0.0
    for _ in range(300):
        worst = min(worst, client.state["O_F_ext_hat_K"][2])
        client.send(**command)
    assert client.move_statuses() == [MoveStatus.kSuccess]  # the press's only
    assert worst >= press - 0.5
    assert table_contacts(ctrl.physics)[0] < 0.2 * -press  # released


def test_a_motion_that_never_commanded_leaves_the_hold_as_it_was():
    ctrl, client = pressed()
    q_hold = ctrl.hold.q.copy()
    assert client.start(JP, IMP) == MoveStatus.kMotionStarted
    ctrl.stop_move(0)
    np.testing.assert_array_equal(ctrl.hold.q, q_hold)
    assert client.state["controller_mode"] == CARTESIAN_IMPEDANCE
    client.idle(200)
    assert table_contacts(ctrl.physics)[0] == pytest.approx(10.0, abs=1.0)


def test_a_reflex_releases_at_the_measured_pose_and_recovery_keeps_that_hold():
    ctrl, client = pressed()
    assert client.start(JP, IMP) == MoveStatus.kMotionStarted
    q = client.state["q"].copy()
    client.send(q_c=q)
    q[0] += 0.5  # a jump: the discontinuity aborts (enforced)
    client.send(q_c=q)
    assert client.move_statuses()[-1] == MoveStatus.kReflexAborted
    assert client.state["controller_mode"] == JOINT_IMPEDANCE
    client.idle(100)
    q_hold = ctrl.hold.q.copy()
    tau = client.state["tau_J"].copy()
    assert ctrl.automatic_error_recovery(0) is None
    client.idle(1)
    np.testing.assert_array_equal(ctrl.hold.q, q_hold)
    np.testing.assert_allclose(client.state["tau_J"], tau, atol=0.05)


def test_the_hold_keeps_its_gains_through_the_setters_and_a_disconnect():
    ctrl, client = pressed()
    force = table_contacts(ctrl.physics)[0]
    ctrl.set_cartesian_impedance(0, [3000.0] * 3 + [300.0] * 3)
    ctrl.set_joint_impedance(0, [100.0] * 7)
    client.idle(100)
    ctrl.end_session(0)  # back to the defaults for the next client
    client.idle(100)
    assert table_contacts(ctrl.physics)[0] == pytest.approx(force, abs=0.1)
