"""Communication constraints in-process, cycle by cycle (docs/fci-behaviour.md "Communication
constraints")."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from tests.fci_helpers import IMP, JP, JV, LoopClient, make_controller

DT = 1e-3


def stream(q0: np.ndarray, k: int, a: float = 2.0, v0: float = 0.0, joint: int = 1) -> np.ndarray:
    """A constant-acceleration waypoint stream on one joint, k cycles after its start."""
    q = q0.copy()
    t = k * DT
    q[joint] += v0 * t + 0.5 * a * t * t
    return q


def started(enforce: bool = True) -> tuple:
    ctrl = make_controller(enforce_motion_limits=enforce)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    return ctrl, c, c.state["q_d"].astype(float)


@pytest.mark.parametrize("gap", [1, 2, 5, 10, 19])
def test_constant_acceleration_stream_is_extrapolated_onto_its_own_waypoints(gap):
    ctrl, c, q0 = started()
    for k in range(0, 30):
        c.send(q_c=stream(q0, k))
    for j in range(1, gap + 1):
        c.send(deliver=False)
        # the substitute waypoint is the stream's own next waypoint: bit for bit as
        # published (float32), and to double rounding (~1e-15) in the float64 history
        expected = stream(q0, 29 + j)
        assert c.state["q_d"].tobytes() == expected.astype(np.float32).tobytes()
        np.testing.assert_allclose(ctrl.reference.q[0], expected, rtol=0, atol=1e-12)
    for k in range(30 + gap, 40 + gap):
        c.send(q_c=stream(q0, k))
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not ctrl.violations.take().any()
    # resuming reports the acceleration it was commanding
    assert float(ctrl.reference.ddq[0, 1]) == pytest.approx(2.0, abs=1e-6)


def test_the_trap_resuming_from_your_own_last_waypoint_trips_14():
    ctrl, c, q0 = started()
    for k in range(0, 200):
        c.send(q_c=stream(q0, k))
    last = stream(q0, 199)
    for _ in range(10):
        c.send(deliver=False)  # the client pauses; the reference keeps moving
    c.send(q_c=last)  # ... and picks up where *it* left off
    assert c.state["robot_mode"] == RobotMode.kReflex
    assert c.state["reflex_reason"][Error.joint_motion_generator_velocity_discontinuity]


def test_the_remedy_resuming_from_q_d_differences_clean():
    ctrl, c, q0 = started()
    for k in range(0, 200):
        c.send(q_c=stream(q0, k))
    for _ in range(10):
        c.send(deliver=False)
    ref = ctrl.reference  # what the state's q_d / dq_d report (in float64 here)
    q = ref.q[0].copy()
    q[1] += (ref.dq[0, 1] + 2.0 * DT) * DT
    c.send(q_c=q)  # resume from the state's q_d
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not ctrl.violations.take().any()


def deliver_backlog(ctrl, c, items: list[tuple[int, np.ndarray]]) -> None:
    """Several datagrams reaching the robot within one cycle, in the given order."""
    command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
    for message_id, q in items:
        command[0] = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
        command["message_id"][0] = message_id
        command["q_c"][0] = q
        ctrl.receive(command, np.ones(1, dtype=bool))
    c.events += ctrl.step()


def test_a_backlog_draining_in_order_gets_the_rewind_and_no_spurious_error():
    ctrl, c, q0 = started()
    stride = dict(a=4.0)
    for k in range(0, 100):
        c.send(q_c=stream(q0, k, **stride))
    # the receive path stalls for 6 cycles: the client answered every state, but
    # nothing arrived; the robot extrapolated
    stalled = []
    for k in range(100, 106):
        stalled.append((int(c.state["message_id"]), stream(q0, k, **stride)))
        c.send(deliver=False)
    now = int(c.state["message_id"])
    # the backlog arrives in order, with the fresh answer last
    deliver_backlog(ctrl, c, [*stalled, (now, stream(q0, 106, **stride))])
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not ctrl.violations.take().any()
    np.testing.assert_allclose(ctrl.reference.q[0], stream(q0, 106, **stride), atol=1e-12)
    for k in range(107, 120):
        c.send(q_c=stream(q0, k, **stride))
    assert not ctrl.violations.take().any()
    assert ctrl.accounting.lost_total[0] == 6


def test_a_reordered_backlog_is_judged_against_the_states_it_answers_and_drains_clean():
    # docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood in for": a
    # reordered backlog "can draw a spurious discontinuity report": here each late datagram is
    # judged against the reference of the state it answers (what it would have met on time), so it
    # does not.
    ctrl, c, q0 = started()  # enforcement on
    stride = dict(a=4.0)
    for k in range(0, 100):
        c.send(q_c=stream(q0, k, **stride))
    stalled = []
    for k in range(100, 106):
        stalled.append((int(c.state["message_id"]), stream(q0, k, **stride)))
        c.send(deliver=False)
    now = int(c.state["message_id"])
    deliver_backlog(ctrl, c, stalled[1:] + stalled[:1] + [(now, stream(q0, 106, **stride))])
    for k in range(107, 115):
        c.send(q_c=stream(q0, k, **stride))
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not ctrl.violations.take().any()


def test_replays_and_duplicates_never_touch_the_history():
    ctrl, c, q0 = started(enforce=False)
    for k in range(0, 50):
        c.send(q_c=stream(q0, k))
    assert not ctrl.violations.take().any()
    now = int(c.state["message_id"])
    before = c.state["q_d"].copy()
    # a replay of the datagram that answered 20 states ago, a duplicate of the last
    # one, then the regular fresh one, all in one cycle
    deliver_backlog(
        ctrl,
        c,
        [(now - 20, stream(q0, 30)), (now - 1, stream(q0, 49)), (now, stream(q0, 50))],
    )
    np.testing.assert_allclose(ctrl.reference.q[0], stream(q0, 50), atol=1e-12)
    assert float(ctrl.reference.dq[0, 1]) == pytest.approx(2.0 * 49.5 * DT, abs=1e-9)
    assert not np.array_equal(before, c.state["q_d"])
    # they answered nothing: the window counts the fresh one only
    assert c.state["control_command_success_rate"] == pytest.approx(1.0)
    # each was judged against the state it answers, where it is consistent
    assert not ctrl.violations.take().any()


def test_an_inconsistent_late_datagram_is_judged_and_reported():
    ctrl, c, q0 = started(enforce=False)
    for k in range(0, 50):
        c.send(q_c=stream(q0, k))
    now = int(c.state["message_id"])
    # an old id carrying today's waypoint: 20 cycles of motion in one
    deliver_backlog(ctrl, c, [(now - 20, stream(q0, 50)), (now, stream(q0, 50))])
    assert ctrl.violations.take()[0, Error.joint_motion_generator_velocity_discontinuity]
    np.testing.assert_allclose(ctrl.reference.q[0], stream(q0, 50), atol=1e-12)


def test_late_datagram_does_not_answer_the_cycle():
    ctrl, c, q0 = started()
    for _ in range(10):
        c.send(q_c=q0)
    late_id = int(c.state["message_id"])
    c.send(deliver=False)
    deliver_backlog(ctrl, c, [(late_id, q0)])  # arrives one cycle late
    assert ctrl.accounting.lost_total[0] == 2
    assert c.state["control_command_success_rate"] == pytest.approx(10 / 12)


def test_extrapolation_stops_at_20_and_the_last_value_holds():
    ctrl, c, q0 = started(enforce=False)
    for k in range(0, 50):
        c.send(q_c=stream(q0, k))
    for _ in range(20):
        c.send(deliver=False)
    held = c.state["q_d"].copy()
    for _ in range(30):
        c.send(deliver=False)
        np.testing.assert_array_equal(c.state["q_d"], held)
        assert not np.any(c.state["dq_d"])


def test_comm_violation_is_independent_of_the_motion_limit_switch():
    ctrl = make_controller(enforce_motion_limits=True, enforce_comm_constraints=False)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(float)
    c.send(q_c=q0)
    for _ in range(25):
        c.send(deliver=False)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert c.move_statuses() == []
    ctrl2 = make_controller(enforce_motion_limits=False, enforce_comm_constraints=True)
    c2 = LoopClient(ctrl2)
    c2.start(JP, IMP)
    c2.send(q_c=c2.state["q_d"].astype(float))
    for _ in range(20):
        c2.send(deliver=False)
    assert c2.move_statuses() == [MoveStatus.kReflexAborted]


def test_a_late_datagram_is_applied_to_the_servo_but_never_recorded():
    ctrl, c, q0 = started(enforce=False)
    for k in range(0, 50):
        c.send(q_c=stream(q0, k))
    late_id = int(c.state["message_id"]) - 3  # echoes a state the history is built on
    late_q = stream(q0, 49) + 0.001  # its intent
    deliver_backlog(ctrl, c, [(late_id, late_q)])
    # the cycle was lost: the history (q_d) is the extrapolated reference ...
    np.testing.assert_allclose(ctrl.reference.q[0], stream(q0, 50), atol=1e-12)
    # ... and the servo was handed the late command's intent
    np.testing.assert_array_equal(ctrl.servo_q[0], late_q)
    c.send(q_c=stream(q0, 51))  # the next command is differenced against the history
    np.testing.assert_array_equal(ctrl.servo_q[0], ctrl.reference.q[0])


def test_a_late_velocity_datagram_drives_the_servo_one_cycle_of_its_dq_c_from_q_d():
    """A late dq_c datagram's intent (docs/fci-behaviour.md "A datagram that turns up late
    replaces the guess it stood in for"): the servo tracks q_d moved by one cycle of its
    dq_c, at dq_c, for the cycle it arrived in; the history is not touched."""
    ctrl = make_controller(enforce_motion_limits=False)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    dq = np.zeros(7)
    for k in range(50):
        dq[1] = 0.002 * k  # a gentle ramp on joint 2
        c.send(dq_c=dq)
    late_id = int(c.state["message_id"]) - 3
    late_dq = dq + 0.001
    command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
    command["message_id"], command["dq_c"] = late_id, late_dq
    q_d = ctrl.reference.q[0].copy()  # the reference the intent moves from
    ctrl.receive(command, np.ones(1, dtype=bool))
    c.events += ctrl.step()
    np.testing.assert_array_equal(ctrl.servo_q[0], q_d + late_dq * DT)
    assert not np.array_equal(ctrl.reference.dq[0], late_dq)  # never recorded


def test_a_client_that_skipped_states_is_judged_against_the_states_it_answers():
    # A slow loop reads the newest state and skips the ones in between: its late
    # datagram is judged against the reference of the state it answers, and the
    # extrapolation (exact for this stream) carries on to the next fresh command.
    ctrl, c, q0 = started()  # enforcement on
    stride = dict(a=4.0)
    for k in range(0, 100):
        c.send(q_c=stream(q0, k, **stride))
    ids = []
    for _ in range(100, 104):  # four cycles go unanswered in time
        ids.append(int(c.state["message_id"]))
        c.send(deliver=False)
    # only the datagram answering the third of them ever arrives (late), then a fresh one
    deliver_backlog(ctrl, c, [(ids[2], stream(q0, 102, **stride))])
    for k in range(105, 110):  # the client goes on answering the newest state
        c.send(q_c=stream(q0, k, **stride))
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not ctrl.violations.take().any()
