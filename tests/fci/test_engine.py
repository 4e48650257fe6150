"""The engine judges and returns verdicts; the controller applies them (the reflex)."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.wire import RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from tests.fci_helpers import IMP, JP, LoopClient, make_controller


def test_a_violation_is_a_verdict_the_controller_applies_after_the_generator_returns():
    ctrl = make_controller(2, enforce_motion_limits=True)
    clients = [LoopClient(ctrl, i) for i in range(2)]
    for client in clients:
        client.start(JP, IMP)
    command = clients[0].command
    command["message_id"] = ctrl.states["message_id"]
    command["q_c"] = ctrl.states["q_d"]
    ctrl.cycle(command)  # the opening commands (the start-pose check only)
    q = ctrl.states["q_d"].copy()
    command["message_id"] = ctrl.states["message_id"]
    command["q_c"] = q
    command["q_c"][1, 3] += 0.01  # 10 rad/s in one cycle: 14 on robot 1 only
    ctrl.receive(command, np.ones(2, dtype=bool))
    ctrl.joint.advance(ctrl.accounting.started)
    # judged, not applied yet: robot 1 still moves, its command is not recorded
    assert ctrl.engine.aborted.tolist() == [False, True]
    assert ctrl.modes.in_motion.all()
    assert not np.array_equal(ctrl.reference.q[1], command["q_c"][1])
    np.testing.assert_array_equal(ctrl.reference.q[0], command["q_c"][0])
    verdicts = ctrl.engine.take_verdicts()
    assert [(v.robot, v.bits) for v in verdicts] == [
        (1, [int(Error.joint_motion_generator_velocity_discontinuity)])
    ]
    assert not ctrl.engine.aborted.any()
    for v in verdicts:
        ctrl.reflex(v.robot, v.bits)
    assert ctrl.modes.robot_mode.tolist() == [int(RobotMode.kMove), int(RobotMode.kReflex)]
    events = ctrl.take_events()
    assert [(e.robot, e.status) for e in events] == [(1, int(MoveStatus.kReflexAborted))]


def test_without_enforcement_a_violation_is_logged_and_no_verdict():
    ctrl = make_controller(1, enforce_motion_limits=False)
    client = LoopClient(ctrl)
    client.start(JP, IMP)
    client.send(q_c=ctrl.states["q_d"][0].copy())
    q_c = ctrl.states["q_d"][0].copy()
    q_c[3] += 0.01
    client.send(q_c=q_c)
    assert ctrl.engine.take_verdicts() == []
    assert ctrl.modes.in_motion[0]
    assert ctrl.violations.seen[0, int(Error.joint_motion_generator_velocity_discontinuity)]
