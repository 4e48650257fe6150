"""The reflex lifecycle and the safety controller, in-process (docs/fci-behaviour.md "Checking is
always on;
aborting is opt-in", "joint_velocity_violation (3)", "cartesian_velocity_violation (4)",
"self_collision_avoidance_violation (2)", "Enabling the violation")."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.errors import Error, error_bits
from franka_sim_gym.fci.events import EventKind
from franka_sim_gym.fci.wire import RobotMode
from franka_sim_gym.fci.wire.protocol import AutomaticErrorRecoveryStatus, MoveStatus
from franka_sim_gym.sim.world import HOME_Q
from tests.fci_helpers import EXT, IMP, JP, JV, NONE, LoopClient, make_controller

FOLD_START = np.array([0.0, 0.3, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])


def bits(*errors: Error) -> np.ndarray:
    return error_bits(*errors)


def step_q(c: LoopClient, q0: np.ndarray, hold: int = 5, step: float = 1.0) -> list:
    for _ in range(hold):
        c.send(q_c=q0)
    q = q0.copy()
    q[0] += step
    return c.send(q_c=q)


def test_enforced_violation_aborts_after_the_state_carrying_the_error():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    events = step_q(c, q0)
    # the same step() published the kReflex state and returned the final reply:
    # the server sends the state first, then the reply
    assert [(e.kind, e.status) for e in events] == [
        (EventKind.MOVE_FINISHED, MoveStatus.kReflexAborted)
    ]
    assert c.state["robot_mode"] == RobotMode.kReflex
    expected = bits(Error.joint_motion_generator_velocity_discontinuity)
    np.testing.assert_array_equal(c.state["errors"], expected)
    np.testing.assert_array_equal(c.state["reflex_reason"], expected)


def test_the_violating_command_is_not_applied():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    step_q(c, q0)
    for _ in range(200):
        c.send(deliver=False)
    assert abs(c.state["q"][0] - q0[0]) < 1e-3  # the 1 rad step never reached physics


def test_unenforced_violation_is_logged_once_per_motion_and_applied(caplog):
    ctrl = make_controller(enforce_motion_limits=False)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.fci"):
        step_q(c, q0, step=0.01)
        q = q0.copy()
        q[0] += 0.01
        step_q(c, q, step=0.01)
    lines = [r.getMessage() for r in caplog.records if "velocity_discontinuity" in r.getMessage()]
    assert len(lines) == 1, lines
    assert "q_c joint 1" in lines[0] and lines[0].endswith("(not enforced)")
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not c.state["errors"].any()
    seen = ctrl.violations.take()
    assert seen[0, Error.joint_motion_generator_velocity_discontinuity]
    assert not ctrl.violations.take().any()  # taken


def test_move_is_refused_while_a_reflex_is_latched():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    step_q(c, c.state["q_d"].astype(float))
    assert ctrl.move(0, int(IMP), int(JP)) == MoveStatus.kCommandNotPossibleRejected


def test_recovery_clears_errors_keeps_reflex_reason_and_a_new_motion_clears_it():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    step_q(c, c.state["q_d"].astype(float))
    assert ctrl.automatic_error_recovery(0) is None
    events = []
    while not events:
        events = ctrl.step()
    assert events[0].status == AutomaticErrorRecoveryStatus.kSuccess
    s = c.state
    assert s["robot_mode"] == RobotMode.kIdle
    assert not s["errors"].any()
    assert s["reflex_reason"][Error.joint_motion_generator_velocity_discontinuity]
    assert c.start(JP, IMP) == MoveStatus.kMotionStarted
    assert not c.state["reflex_reason"].any()
    q0 = c.state["q_d"].astype(float)
    for _ in range(10):
        c.send(q_c=q0)
    assert c.finish(q_c=q0) == MoveStatus.kSuccess


def test_recovery_waits_for_standstill_after_a_fast_abort():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    v, a = 0.0, 0.0
    c.send(dq_c=np.zeros(7))  # the opening command: at rest
    for _ in range(400):  # joint 1 to 2 rad/s, jerk- and acceleration-limited
        a = min(9.0, a + 4.0) if v < 2.0 - 0.5 else max(0.0, a - 4.0)
        v = min(2.0, v + a * 1e-3)
        c.send(dq_c=[v, 0, 0, 0, 0, 0, 0])
    assert c.state["dq"][0] > 1.5
    c.send(dq_c=[60.0, 0, 0, 0, 0, 0, 0])  # a step: aborted at speed
    assert c.state["robot_mode"] == RobotMode.kReflex
    ctrl.automatic_error_recovery(0)
    cycles, events = 0, []
    while not events:
        events = ctrl.step()
        cycles += 1
    assert 50 < cycles <= 700
    assert np.all(np.abs(ctrl.physics.dq) < 0.005) or cycles == 700


def test_a_reflex_survives_a_disconnect_until_recovery():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    step_q(c, c.state["q_d"].astype(float))
    ctrl.end_session(0)
    ctrl.step()
    assert c.state["robot_mode"] == RobotMode.kReflex
    assert c.state["errors"].any()
    assert ctrl.move(0, int(IMP), int(JP)) == MoveStatus.kCommandNotPossibleRejected


def test_commanded_envelope_violation_latches_3_with_13():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    # joint 4 ramped smoothly (5 rad/s^2, within the jerk limit) past its 2.62 rad/s
    for k in range(1, 700):
        v = min(5.0 * k * 1e-3 * min(1.0, k / 200), 2.7)
        c.send(dq_c=[0, 0, 0, v, 0, 0, 0])
        if c.state["robot_mode"] != RobotMode.kMove:
            break
    expected = bits(
        Error.joint_motion_generator_velocity_limits_violation, Error.joint_velocity_violation
    )
    np.testing.assert_array_equal(c.state["reflex_reason"], expected)


def test_non_finite_command_is_refused_even_without_enforcement():
    ctrl = make_controller(enforce_motion_limits=False)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    c.send(q_c=q0)
    bad = q0.copy()
    bad[4] = np.inf
    c.send(q_c=bad)
    assert np.all(np.isfinite(c.state["q_d"]))
    assert c.state["robot_mode"] == RobotMode.kMove
    assert ctrl.violations.take()[0, Error.joint_motion_generator_position_limits_violation]


def test_non_finite_command_with_enforcement_latches_the_generator_limits_violation():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    c.send(dq_c=np.zeros(7))
    c.send(dq_c=[0, np.nan, 0, 0, 0, 0, 0])
    assert c.state["robot_mode"] == RobotMode.kReflex
    assert c.state["reflex_reason"][Error.joint_motion_generator_velocity_limits_violation]


def torque_ramp(
    c: LoopClient, joint: int, rate: float = 900.0, peak: float = 12.0, cycles: int = 3000
) -> None:
    """Ramp one joint's torque at ``rate`` Nm/s (under the 1000 Nm/s limit) up to ``peak``."""
    for k in range(1, cycles):
        tau = np.zeros(7)
        tau[joint] = min(peak, rate * k * 1e-3)
        c.send(tau_J_d=tau)
        if c.state["robot_mode"] != RobotMode.kMove:
            return


def test_measured_joint_velocity_in_torque_mode_latches_3_alone():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(NONE, EXT)
    torque_ramp(c, joint=6)
    assert c.state["robot_mode"] == RobotMode.kReflex
    np.testing.assert_array_equal(c.state["reflex_reason"], bits(Error.joint_velocity_violation))
    # beyond the envelope (5.26 - 1e-3 rad/s at joint 7) plus the 0.1 rad/s margin
    assert abs(c.state["dq"][6]) > 5.26 + 0.09


def test_measured_cartesian_speed_outranks_joint_velocity():
    ctrl = make_controller(enforce_motion_limits=True)
    T = np.eye(4)
    T[0, 3] = 1.0  # the EE 1 m out, sideways: joint 7 spinning moves it at 1 m x omega
    ctrl.set_ne_to_ee(0, frames.to_wire(T))
    c = LoopClient(ctrl)
    c.start(NONE, EXT)
    torque_ramp(c, joint=6)
    np.testing.assert_array_equal(
        c.state["reflex_reason"], bits(Error.cartesian_velocity_violation)
    )
    assert abs(c.state["dq"][6]) < 5.26  # joint 7 was still inside its envelope


def test_self_collision_fold_latches_2_before_joint_4_reaches_its_stop():
    ctrl = make_controller(enforce_motion_limits=True)
    ctrl.reset(0, FOLD_START)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    for k in range(12000):
        r = min(1.0, k / 500)
        r = r * r * (3 - 2 * r)
        c.send(dq_c=[0, 0, 0, -0.1 * r, 0.2 * r, 0, 0])
        if c.state["robot_mode"] != RobotMode.kMove:
            break
    np.testing.assert_array_equal(
        c.state["reflex_reason"], bits(Error.self_collision_avoidance_violation)
    )
    assert c.state["q"][3] > -3.0481 + 0.05


def test_no_monitored_pair_is_within_50_mm_at_home():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    for _ in range(100):
        c.send(q_c=HOME_Q)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not ctrl.violations.take().any()


def test_extrapolated_waypoints_are_checked_not_clamped():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    # joint 1 accelerating at 9 rad/s^2 (jerk-limited start) towards its 2.62 rad/s
    q, v, a = q0.copy(), 0.0, 0.0
    c.send(q_c=q0)  # the opening command: at rest where the robot is
    for _ in range(280):
        a = min(9.0, a + 4000.0 * 1e-3)
        v += a * 1e-3
        q[0] += v * 1e-3
        c.send(q_c=q)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert 2.4 < float(c.state["dq_d"][0]) < 2.619
    for _ in range(19):  # the link drops: the reference keeps accelerating into the envelope
        c.send(deliver=False)
        if c.state["robot_mode"] != RobotMode.kMove:
            break
    assert c.state["robot_mode"] == RobotMode.kReflex
    assert c.state["reflex_reason"][Error.joint_motion_generator_velocity_limits_violation]


@pytest.mark.parametrize("enforce", [True, False])
def test_twenty_lost_cycles_abort_with_25_only_when_enforced(enforce):
    ctrl = make_controller(enforce_comm_constraints=enforce)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    for _ in range(10):
        c.send(q_c=q0)
    for k in range(1, 21):
        c.send(deliver=False)
        if k < 20:
            assert c.state["robot_mode"] == RobotMode.kMove
    if enforce:
        assert c.state["robot_mode"] == RobotMode.kReflex
        np.testing.assert_array_equal(
            c.state["reflex_reason"], bits(Error.communication_constraints_violation)
        )
        assert c.move_statuses() == [MoveStatus.kReflexAborted]
    else:
        assert c.state["robot_mode"] == RobotMode.kMove
        assert ctrl.violations.take()[0, Error.communication_constraints_violation]
