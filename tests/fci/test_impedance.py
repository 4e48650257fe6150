"""ControllerMode::kCartesianImpedance and SetCartesianImpedance (fci/impedance.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.wire import MoveControllerMode, MoveMotionGeneratorMode
from franka_sim_gym.fci.wire.statuses import MoveStatus, SetterStatus
from tests.fci.contact.test_contact_sensing import thresholds
from tests.fci_helpers import JP, LoopClient, make_controller
from tests.sim.test_scene import OVER_THE_TABLE, table_contacts

CARTESIAN_IMPEDANCE = MoveControllerMode.kCartesianImpedance
CARTESIAN_POSITION = MoveMotionGeneratorMode.kCartesianPosition


def start(generator, **config):
    ctrl = make_controller(1, **config)
    ctrl.reset([0], OVER_THE_TABLE[None])
    client = LoopClient(ctrl)
    ctrl.set_collision_behavior(0, thresholds(force=(100.0, 100.0)))
    assert client.start(generator, CARTESIAN_IMPEDANCE) == MoveStatus.kMotionStarted
    return ctrl, client


@pytest.mark.parametrize("stiffness", [500.0, 1500.0])
def test_a_pose_commanded_into_the_table_presses_with_stiffness_times_depth(stiffness):
    """The pose generator lowers the commanded flange 20 cm, 2 cm under the table's
    surface (the flange starts 18 cm above it); the Cartesian servo holds it there."""
    ctrl, client = start(CARTESIAN_POSITION)
    assert ctrl.set_cartesian_impedance(0, [stiffness] * 3 + [300.0] * 3) == SetterStatus.kSuccess
    pose = client.state["O_T_EE_c"].astype(np.float64)
    z0, depth, duration = pose[14], 0.2, 3000
    for k in range(duration + 1000):
        s = min(k / duration, 1.0)
        pose[14] = z0 - depth * 0.5 * (1 - math.cos(math.pi * s))
        client.send(O_T_EE_c=pose)
    assert client.move_statuses() == []  # no reflex: the thresholds are 100 N
    force, _, _ = table_contacts(ctrl.physics)
    expected = stiffness * (client.state["O_T_EE"][14] - pose[14])  # spring stretch x K
    assert force == pytest.approx(expected, rel=0.05)
    assert force == pytest.approx(stiffness * 0.02, rel=0.25)  # the 2 cm of the issue
    # The robot senses it: the wrench at K is the press, pushing down.
    assert client.state["O_F_ext_hat_K"][2] == pytest.approx(-force, rel=0.05)


def test_under_joint_generators_the_servo_holds_the_forward_kinematics_of_q_d():
    ctrl, client = start(JP)
    q = client.state["q_d"].astype(np.float64)
    target = q.copy()
    for k in range(1500):  # joint 4 by 0.2 rad in 1.5 s, then hold
        target[3] = q[3] + 0.2 * 0.5 * (1 - math.cos(math.pi * min(k / 1000, 1.0)))
        client.send(q_c=target)
    np.testing.assert_allclose(client.state["q"], target, atol=2e-3)
    assert client.move_statuses() == []


@pytest.mark.parametrize(
    "K_x",
    [[5.0, 100, 100, 10, 10, 10], [100, 100, 3001.0, 10, 10, 10], [100, 100, 100, 10, 10, 0.5],
     [100, 100, np.nan, 10, 10, 10], [100, 100, 100, 10, 10]],
)  # fmt: skip
def test_set_cartesian_impedance_refuses_what_libfranka_documents_as_out_of_range(K_x):
    ctrl = make_controller(1)
    before = ctrl.impedance.stiffness.copy()
    assert ctrl.set_cartesian_impedance(0, K_x) == SetterStatus.kInvalidArgumentRejected
    np.testing.assert_array_equal(ctrl.impedance.stiffness, before)


def test_a_new_client_starts_from_the_default_cartesian_stiffness():
    ctrl = make_controller(1)
    default = ctrl.impedance.stiffness[0].copy()
    assert ctrl.set_cartesian_impedance(0, [500.0] * 3 + [50.0] * 3) == SetterStatus.kSuccess
    ctrl.end_session(0)
    np.testing.assert_array_equal(ctrl.impedance.stiffness[0], default)
