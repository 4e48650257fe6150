"""Contact and collision in the controller (fci/contact/sensing.py): the contact group of
the RobotState, SetCollisionBehavior applied, joint_reflex / cartesian_reflex."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.contact.collision import THRESHOLD_NAMES
from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.events import EventKind
from franka_sim_gym.fci.frames import from_wire
from franka_sim_gym.fci.wire import MoveMotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.statuses import MoveStatus, SetterStatus
from tests.fci_helpers import LoopClient, make_controller
from tests.sim.test_scene import OVER_THE_TABLE

CARTESIAN_VELOCITY = MoveMotionGeneratorMode.kCartesianVelocity


def thresholds(torque=(100.0, 100.0), force=(10.0, 20.0)) -> dict:
    """Eight arrays from (lower, upper) torque and force thresholds, both phases."""
    t_lo, t_up = [torque[0]] * 7, [torque[1]] * 7
    f_lo, f_up = [force[0]] * 6, [force[1]] * 6
    return dict(zip(THRESHOLD_NAMES, (t_lo, t_up, t_lo, t_up, f_lo, f_up, f_lo, f_up), strict=True))


def over_the_table(**config):
    ctrl = make_controller(1, **config)
    ctrl.reset([0], OVER_THE_TABLE[None])
    return ctrl, LoopClient(ctrl)


def descend(client: LoopClient, cycles: int = 5000, speed: float = 0.05):
    """A Cartesian velocity motion straight down at ``speed`` (a 0.5 s cosine ramp);
    stops at the Move's end. Returns the states seen (copies)."""
    seen = []
    for k in range(cycles):
        t = (k + 1) * 1e-3
        v = speed * 0.5 * (1 - math.cos(math.pi * min(t / 0.5, 1.0)))
        events = client.send(O_dP_EE_c=[0.0, 0.0, -v, 0.0, 0.0, 0.0])
        seen.append(client.state.copy())
        if any(e.kind is EventKind.MOVE_FINISHED for e in events):
            break
    return seen


def test_a_descent_onto_the_table_trips_cartesian_reflex_after_the_contact_flag():
    ctrl, client = over_the_table(enforce_motion_limits=True)
    assert ctrl.set_collision_behavior(0, thresholds()) == SetterStatus.kSuccess
    client.start(CARTESIAN_VELOCITY)
    seen = descend(client)
    assert client.move_statuses() == [MoveStatus.kReflexAborted]
    final = seen[-1]
    assert final["robot_mode"] == RobotMode.kReflex
    assert final["errors"][Error.cartesian_reflex]
    assert final["reflex_reason"][Error.cartesian_reflex]
    assert final["cartesian_collision"][2] == 1.0
    contact = [k for k, s in enumerate(seen) if s["cartesian_contact"][2] > 0]
    assert contact and contact[0] < len(seen) - 1  # the contact flag came first
    # The abort came as the estimate crossed 20 N, with the flange at the table.
    assert final["O_F_ext_hat_K"][2] < -20.0 and seen[-2]["O_F_ext_hat_K"][2] > -20.0
    assert abs(final["O_T_EE"][14]) < 5e-3


def test_recovery_clears_the_latched_collision_flags():
    ctrl, client = over_the_table(enforce_motion_limits=True)
    ctrl.set_collision_behavior(0, thresholds())
    client.start(CARTESIAN_VELOCITY)
    descend(client)
    assert client.state["cartesian_collision"].any()
    assert ctrl.automatic_error_recovery(0) is None  # answered when the arm is still
    client.idle(1000)
    assert any(e.kind is EventKind.RECOVERY_FINISHED for e in client.events)
    assert client.state["robot_mode"] == RobotMode.kIdle
    assert not client.state["cartesian_collision"].any()
    assert not client.state["errors"][Error.cartesian_reflex]
    assert client.state["reflex_reason"][Error.cartesian_reflex]  # kept, as on the robot


def test_without_enforcement_a_collision_is_flagged_and_logged_but_the_motion_goes_on():
    ctrl, client = over_the_table(enforce_motion_limits=False)
    ctrl.set_collision_behavior(0, thresholds())
    client.start(CARTESIAN_VELOCITY)
    descend(client, cycles=4500)
    assert client.move_statuses() == []
    assert client.state["robot_mode"] == RobotMode.kMove
    assert client.state["cartesian_collision"][2] == 1.0
    assert ctrl.violations.take()[0, Error.cartesian_reflex]


def test_contact_flags_clear_when_the_force_falls_below_the_lower_threshold():
    ctrl, client = over_the_table(enforce_motion_limits=True)
    ctrl.set_collision_behavior(0, thresholds(force=(10.0, 1000.0)))
    client.start(CARTESIAN_VELOCITY)
    seen = descend(client, cycles=4000)
    assert seen[-1]["cartesian_contact"][2] == 1.0
    for _ in range(600):  # back up at 5 cm/s: off the table
        client.send(O_dP_EE_c=[0.0, 0.0, 0.05, 0.0, 0.0, 0.0])
    assert client.state["cartesian_contact"].sum() == 0.0
    assert np.abs(client.state["O_F_ext_hat_K"]).max() < 1.0


def test_refused_thresholds_keep_the_ones_in_force():
    ctrl, _ = over_the_table()
    assert ctrl.set_collision_behavior(0, thresholds(force=(10.0, 20.0))) == SetterStatus.kSuccess
    bad = thresholds(force=(10.0, 20.0))
    bad["upper_force_thresholds_nominal"] = [20.0, 20.0, np.nan, 20.0, 20.0, 20.0]
    assert ctrl.set_collision_behavior(0, bad) == SetterStatus.kInvalidArgumentRejected
    np.testing.assert_array_equal(ctrl.contact.behavior.upper_force[0, 1], [20.0] * 6)


def test_a_new_client_starts_from_the_default_thresholds():
    ctrl, _ = over_the_table()
    default = ctrl.contact.behavior.upper_force[0].copy()
    ctrl.set_collision_behavior(0, thresholds(force=(50.0, 60.0)))
    ctrl.end_session(0)
    np.testing.assert_array_equal(ctrl.contact.behavior.upper_force[0], default)


def test_the_published_estimate_is_zero_at_rest_and_after_a_reset():
    ctrl, client = over_the_table()
    client.idle(500)
    assert np.abs(client.state["tau_ext_hat_filtered"]).max() < 0.05
    assert np.abs(client.state["O_F_ext_hat_K"]).max() < 0.1
    assert client.state["joint_contact"].sum() == client.state["cartesian_contact"].sum() == 0


def test_a_payload_nobody_configured_reads_as_its_weight_and_setload_takes_it_away():
    """1 kg fixed 5 cm out on the flange: the robot holds it (idle) and, not told of it,
    senses its weight as an external force (held up: +z, the force the robot exerts);
    configured with SetLoad, the model explains it and nothing external remains."""
    from franka_sim_gym.fci.config import ControllerConfig
    from franka_sim_gym.fci.controller import FciController
    from franka_sim_gym.sim.arm import ArmPhysics

    ctrl = FciController(ArmPhysics(1, payload=(1.0, 0.0, 0.0, 0.05)), ControllerConfig())
    client = LoopClient(ctrl)
    client.idle(1500)
    weight = 9.81
    assert client.state["O_F_ext_hat_K"][2] == pytest.approx(weight, rel=0.05)
    assert ctrl.set_load(0, 1.0, [0.0, 0.0, 0.05], np.zeros(9)) == SetterStatus.kSuccess
    client.idle(1500)
    assert abs(client.state["O_F_ext_hat_K"][2]) < 0.05 * weight


def test_the_wrench_is_estimated_at_k_and_expressed_in_its_axes():
    """SetEEToK 10 cm along the flange's z and turned 90 deg about it: pressing on the
    table, O_F_ext_hat_K is the same force (the table pushes where it pushes), its
    moment is taken about K, and K_F_ext_hat_K is that wrench in K's turned axes."""
    ctrl, client = over_the_table(enforce_motion_limits=True)
    ctrl.set_collision_behavior(0, thresholds(force=(100.0, 200.0)))
    EE_T_K = np.eye(4)
    EE_T_K[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    EE_T_K[:3, 3] = [0.0, 0.0, 0.1]
    assert ctrl.set_ee_to_k(0, EE_T_K.T.reshape(16)) == SetterStatus.kSuccess  # wire order
    client.start(CARTESIAN_VELOCITY)
    descend(client, cycles=4200)
    s = client.state
    O_F, K_F = s["O_F_ext_hat_K"].astype(float), s["K_F_ext_hat_K"].astype(float)
    assert O_F[2] < -20.0  # pressing down
    O_T_K = from_wire(s["O_T_EE"]) @ EE_T_K
    R = O_T_K[:3, :3]
    np.testing.assert_allclose(K_F[:3], R.T @ O_F[:3], atol=1e-3)
    np.testing.assert_allclose(K_F[3:], R.T @ O_F[3:], atol=1e-3)
    # The moment about K, 10 cm under the flange along the flange's z (pointing down)
    # and so about at the contact: smaller than the same force's moment at the flange.
    p_flange = from_wire(s["O_T_EE"])[:3, 3]
    moment_at_flange = O_F[3:] + np.cross(O_T_K[:3, 3] - p_flange, O_F[:3])
    assert np.linalg.norm(O_F[3:]) < np.linalg.norm(moment_at_flange)
