"""The controller in-process: one call = one 1 ms cycle, deterministic, no sockets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.events import EventKind
from franka_sim_gym.fci.wire import ControllerMode, MotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.protocol import AutomaticErrorRecoveryStatus, MoveStatus, SetterStatus
from franka_sim_gym.sim.world import HOME_Q
from tests.fci_helpers import EXT, IMP, JP, JV, NONE, LoopClient, make_controller

HOME_FLANGE = np.array([0.306891, 0.0, 0.590282])
#: docs/fr3-model.md §6: gravity at home, no EE load.
HOME_GRAVITY = np.array([0.0, -1.7090, -0.6395, 18.9582, 0.7919, 1.5879, 0.0])


@pytest.fixture
def ctrl():
    return make_controller()


def test_message_id_starts_at_one_and_strictly_increases(ctrl):
    assert int(ctrl.states[0]["message_id"]) == 1
    ids = []
    for _ in range(5):
        ctrl.step()
        ids.append(int(ctrl.states[0]["message_id"]))
    assert ids == [2, 3, 4, 5, 6]


def test_idle_state_fields_at_home(ctrl):
    s = ctrl.states[0]
    np.testing.assert_allclose(s["q"], HOME_Q, atol=1e-6)
    np.testing.assert_array_equal(s["theta"], s["q"])
    np.testing.assert_array_equal(s["q_d"], s["q"])  # idle: q_d is the measured q
    assert not np.any(s["dq_d"]) and not np.any(s["ddq_d"]) and not np.any(s["tau_J_d"])
    T = frames.from_wire(s["O_T_EE"].astype(float))
    np.testing.assert_allclose(T[:3, 3], HOME_FLANGE, atol=1e-4)
    np.testing.assert_allclose(T[3], [0, 0, 0, 1])
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6)
    np.testing.assert_array_equal(s["O_T_EE_d"], s["O_T_EE"])
    np.testing.assert_array_equal(s["O_T_EE_c"], s["O_T_EE"])
    np.testing.assert_allclose(s["O_ddP_O"], [0, 0, -9.81], rtol=1e-6)
    np.testing.assert_allclose(s["elbow"], [HOME_Q[2], -1.0], atol=1e-6)
    assert s["robot_mode"] == RobotMode.kIdle
    assert s["motion_generator_mode"] == MotionGeneratorMode.kIdle
    assert s["controller_mode"] == ControllerMode.kJointImpedance
    assert s["control_command_success_rate"] == 0.0
    np.testing.assert_array_equal(s["F_T_EE"], frames.IDENTITY16)


def test_tau_J_is_the_measured_torque_including_gravity(ctrl):
    for _ in range(50):
        ctrl.step()
    np.testing.assert_allclose(ctrl.states[0]["tau_J"], HOME_GRAVITY, atol=0.05 * 19)
    np.testing.assert_allclose(ctrl.states[0]["tau_J"][3], HOME_GRAVITY[3], rtol=0.02)


def test_idle_hold_is_calm(ctrl):
    q0 = ctrl.states[0]["q"].copy()
    peak = 0.0
    for _ in range(2000):
        ctrl.step()
        peak = max(peak, float(np.max(np.abs(ctrl.states[0]["dq"]))))
    assert peak < 1e-3, f"a joint moves at {peak} rad/s while holding"
    assert np.max(np.abs(ctrl.states[0]["q"] - q0)) < 1e-4


def cosine(q0, t, duration=1.0, amplitude=0.2):
    q = q0.copy()
    q[[3, 4, 6]] += amplitude * (1 - math.cos(2 * math.pi * t / duration))
    return q


def test_joint_position_motion_tracks_and_finishes_with_success(ctrl):
    c = LoopClient(ctrl)
    assert c.start(JP, IMP) == MoveStatus.kMotionStarted
    assert c.state["robot_mode"] == RobotMode.kMove
    assert c.state["motion_generator_mode"] == MotionGeneratorMode.kJointPosition
    q0 = c.state["q_d"].astype(float)
    worst = 0.0
    for k in range(1, 1001):
        c.send(q_c=cosine(q0, k * 1e-3))
        np.testing.assert_allclose(c.state["q_d"], cosine(q0, k * 1e-3), atol=1e-6)
        worst = max(worst, float(np.max(np.abs(c.state["q"] - c.state["q_d"]))))
    assert worst < 1e-2
    assert c.finish(q_c=cosine(q0, 1.0)) == MoveStatus.kSuccess
    assert c.state["robot_mode"] == RobotMode.kIdle
    assert c.state["motion_generator_mode"] == MotionGeneratorMode.kIdle
    assert c.state["control_command_success_rate"] == 0.0


def test_dq_d_and_ddq_d_are_the_backward_differences_of_q_c(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    qs = [q0 + 0.5 * 2.0 * (k * 1e-3) ** 2 * np.eye(7)[0] for k in range(1, 6)]
    for q in qs:
        c.send(q_c=q)
    dq = (qs[-1] - qs[-2]) / 1e-3
    ddq = ((qs[-1] - qs[-2]) - (qs[-2] - qs[-3])) / 1e-6
    np.testing.assert_allclose(c.state["dq_d"], dq.astype(np.float32), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(c.state["ddq_d"][0], ddq[0], rtol=1e-3)


def test_joint_velocity_motion_integrates_dq_c(ctrl):
    c = LoopClient(ctrl)
    assert c.start(JV, IMP) == MoveStatus.kMotionStarted
    assert c.state["motion_generator_mode"] == MotionGeneratorMode.kJointVelocity
    q0 = c.state["q"].astype(float)
    n = 1000
    for k in range(n):
        v = 0.2 * math.sin(math.pi * k / n) ** 2
        c.send(dq_c=[0, 0, 0, v, 0, 0, 0])
        assert c.state["dq_d"][3] == pytest.approx(v, abs=1e-6)
    assert c.finish(dq_c=np.zeros(7)) == MoveStatus.kSuccess
    for _ in range(200):
        c.send(deliver=False)
    # integral of 0.2 sin^2 over 1 s = 0.1 rad on joint 4
    assert c.state["q"][3] - q0[3] == pytest.approx(0.1, abs=3e-3)


def test_torque_motion_of_zero_torque_holds_and_freezes_q_d(ctrl):
    c = LoopClient(ctrl)
    assert c.start(NONE, EXT) == MoveStatus.kMotionStarted
    assert c.state["motion_generator_mode"] == MotionGeneratorMode.kNone
    assert c.state["controller_mode"] == ControllerMode.kExternalController
    q_hold = c.state["q_d"].copy()
    q0 = c.state["q"].astype(float)
    for _ in range(2000):
        c.send(tau_J_d=np.zeros(7))
        np.testing.assert_array_equal(c.state["q_d"], q_hold)
        assert not np.any(c.state["dq_d"])
    assert np.max(np.abs(c.state["q"] - q0)) < 1e-3
    assert c.finish(tau_J_d=np.zeros(7)) == MoveStatus.kSuccess
    assert c.state["controller_mode"] != ControllerMode.kExternalController


def test_torque_command_moves_the_arm_and_is_echoed_in_tau_J_d(ctrl):
    c = LoopClient(ctrl)
    c.start(NONE, EXT)
    q0 = c.state["q"].astype(float)
    tau = np.array([0, 0, 0, 0, 0, 0, 0.2])
    for _ in range(300):
        c.send(tau_J_d=tau)
    np.testing.assert_allclose(c.state["tau_J_d"], tau, atol=1e-7)
    assert c.state["q"][6] - q0[6] > 0.05  # 0.2 Nm on joint 7 spins it
    assert abs(c.state["q"][0] - q0[0]) < 1e-3


def test_stop_move_preempts_the_running_motion(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    for _ in range(10):
        c.send(q_c=q0)
    assert ctrl.stop_move(0) == 0
    c.send(q_c=q0)
    assert c.move_statuses() == [MoveStatus.kPreempted]
    assert c.state["robot_mode"] == RobotMode.kIdle
    assert c.state["motion_generator_mode"] == MotionGeneratorMode.kIdle


def test_move_during_a_move_preempts_and_reseeds_from_standstill(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    for k in range(1, 200):
        c.send(q_c=cosine(q0, k * 1e-3))
    assert c.start(JP, IMP) == MoveStatus.kMotionStarted
    assert c.move_statuses() == [MoveStatus.kPreempted]
    # the new motion starts at rest at the measured pose
    assert not np.any(c.state["dq_d"]) and not np.any(c.state["ddq_d"])
    assert np.max(np.abs(c.state["q_d"] - c.state["q"])) < 5e-3


def test_success_rate_divides_by_what_the_window_holds(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    for _ in range(3):
        c.send(q_c=q0)
    assert c.state["control_command_success_rate"] == pytest.approx(1.0)
    c.send(deliver=False)
    assert c.state["control_command_success_rate"] == pytest.approx(0.75)
    for _ in range(200):
        c.send(q_c=q0)
    assert c.state["control_command_success_rate"] == pytest.approx(1.0)
    for _ in range(10):
        c.send(deliver=False)
    assert c.state["control_command_success_rate"] == pytest.approx(0.90)
    c.finish(q_c=q0)
    assert c.state["control_command_success_rate"] == 0.0


def test_late_and_future_ids_do_not_answer_the_cycle(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    c.send(q_c=q0)
    now = int(c.state["message_id"])
    c.send(q_c=q0, message_id=now - 1)  # late
    assert c.state["control_command_success_rate"] == pytest.approx(0.5)
    c.send(q_c=q0, message_id=now + 100)  # never published: a lost cycle
    assert c.state["control_command_success_rate"] == pytest.approx(1 / 3)


def test_non_finite_command_is_refused(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    c.send(q_c=q0)
    bad = q0.copy()
    bad[2] = np.nan
    c.send(q_c=bad)
    assert np.all(np.isfinite(c.state["q_d"])) and np.all(np.isfinite(c.state["q"]))
    np.testing.assert_allclose(c.state["q_d"], q0, atol=1e-9)


def test_lost_cycle_is_extrapolated_at_frozen_acceleration(ctrl):
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    a = 1.0
    k = 0
    for k in range(1, 11):
        c.send(q_c=q0 + 0.5 * a * (k * 1e-3) ** 2 * np.eye(7)[1])
    c.send(deliver=False)
    expected = q0[1] + 0.5 * a * (11e-3) ** 2
    assert float(c.state["q_d"][1]) == pytest.approx(expected, abs=1e-7)


def test_set_ne_to_ee_moves_the_measured_frame(ctrl):
    T = np.eye(4)
    T[2, 3] = 0.5
    assert ctrl.set_ne_to_ee(0, frames.to_wire(T)) == SetterStatus.kSuccess
    ctrl.step()
    s = ctrl.states[0]
    np.testing.assert_allclose(s["F_T_EE"], frames.to_wire(T), atol=1e-7)
    np.testing.assert_allclose(s["NE_T_EE"], frames.to_wire(T), atol=1e-7)
    pose = frames.from_wire(s["O_T_EE"].astype(float))
    # at home the flange z axis points down: the EE is 0.5 m below the flange
    np.testing.assert_allclose(pose[:3, 3], HOME_FLANGE + [0, 0, -0.5], atol=1e-4)
    bad = frames.to_wire(T)
    bad[15] = 2.0
    assert ctrl.set_ne_to_ee(0, bad) == SetterStatus.kInvalidArgumentRejected


def test_automatic_error_recovery_answers_after_standstill(ctrl):
    assert ctrl.automatic_error_recovery(0) is None
    assert ctrl.states[0]["robot_mode"] == RobotMode.kAutomaticErrorRecovery
    events = []
    cycles = 0
    while not events:
        events = ctrl.step()
        cycles += 1
    assert events[0].kind is EventKind.RECOVERY_FINISHED
    assert events[0].status == AutomaticErrorRecoveryStatus.kSuccess
    assert cycles == 50  # the arm is at rest: 50 consecutive still cycles
    assert ctrl.states[0]["robot_mode"] == RobotMode.kIdle


def test_move_rejects_invalid_modes(ctrl):
    assert ctrl.move(0, 7, 0) == MoveStatus.kInvalidArgumentRejected
    assert ctrl.move(0, 0, 9) == MoveStatus.kInvalidArgumentRejected
    assert ctrl.move(0, int(IMP), int(NONE)) == MoveStatus.kInvalidArgumentRejected


def test_same_commands_give_the_same_trajectory_bit_for_bit():
    def run():
        ctrl = make_controller()
        c = LoopClient(ctrl)
        c.start(JP, IMP)
        q0 = c.state["q_d"].astype(float)
        out = []
        for k in range(1, 300):
            c.send(deliver=(k % 7 != 0), q_c=cosine(q0, k * 1e-3))
            out.append(ctrl.states.tobytes())
        return b"".join(out)

    assert run() == run()


def test_batch_of_arms_is_independent():
    ctrl = make_controller(n=3)
    c1 = LoopClient(ctrl, 1)
    c1.start(JP, IMP)
    q0 = c1.state["q_d"].astype(float)
    for k in range(1, 300):
        c1.send(q_c=cosine(q0, k * 1e-3))
    assert ctrl.states[0]["robot_mode"] == RobotMode.kIdle
    assert ctrl.states[1]["robot_mode"] == RobotMode.kMove
    np.testing.assert_allclose(ctrl.states[0]["q"], HOME_Q, atol=1e-4)
    np.testing.assert_allclose(ctrl.states[2]["q"], HOME_Q, atol=1e-4)
    assert abs(ctrl.states[1]["q"][3] - q0[3]) > 0.1
