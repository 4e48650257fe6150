"""Every one of the twelve v10 TCP commands is answered, with the robot's status
(libfranka has no reply timeout: one unanswered request hangs a client for ever)."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.frames import IDENTITY16
from franka_sim_gym.fci.wire import protocol as p
from tests.raw_client import RawClient

pytestmark = pytest.mark.socket

I16 = tuple(IDENTITY16.tolist())
VALID_REQUESTS = {
    p.Command.kSetCollisionBehavior: p.SetCollisionBehaviorRequest(
        *([(20.0,) * 7] * 4 + [(30.0,) * 6] * 4)
    ),
    p.Command.kSetJointImpedance: p.SetJointImpedanceRequest((3000.0,) * 7),
    p.Command.kSetCartesianImpedance: p.SetCartesianImpedanceRequest((3000.0,) * 3 + (300.0,) * 3),
    p.Command.kSetGuidingMode: p.SetGuidingModeRequest((True,) * 6, False),
    p.Command.kSetEEToK: p.SetEEToKRequest(I16),
    p.Command.kSetNEToEE: p.SetNEToEERequest(I16),
    p.Command.kSetLoad: p.SetLoadRequest(
        0.5, (0.0, 0.0, 0.05), (0.001, 0, 0, 0, 0.001, 0, 0, 0, 0.001)
    ),
    p.Command.kStopMove: p.StopMoveRequest(),
    p.Command.kAutomaticErrorRecovery: p.AutomaticErrorRecoveryRequest(),
    p.Command.kGetRobotModel: p.GetRobotModelRequest(),
}


@pytest.mark.parametrize("command", list(VALID_REQUESTS), ids=lambda c: c.name)
def test_every_command_is_answered_with_success(serve, command):
    server = serve()
    client = RawClient(server.host)
    assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
    client.state()
    command_id = client.request(command, VALID_REQUESTS[command].payload())
    reply = client.reply(command_id, timeout=3.0)
    assert reply.command == command and reply.command_id == command_id
    assert reply.payload[0] == 0, f"{command.name} answered {reply.payload[0]}"
    assert "failed" not in server.log()
    client.close()


def test_move_is_answered_twice_started_then_preempted_by_stop_move(serve):
    server = serve()
    client = RawClient(server.host)
    client.connect()
    client.state()
    move = client.request(
        p.Command.kMove,
        p.MoveRequest(0, 0, p.DEFAULT_DEVIATION, p.DEFAULT_DEVIATION, False, (0.0,) * 7).payload(),
    )
    assert client.reply(move).payload[0] == p.MoveStatus.kMotionStarted
    stop = client.request(p.Command.kStopMove)
    assert client.reply(stop).payload[0] == p.StopMoveStatus.kSuccess
    assert client.reply(move).payload[0] == p.MoveStatus.kPreempted
    state = client.latest_state()
    assert state["robot_mode"] == 1 and state["motion_generator_mode"] == 0
    assert np.all(np.isfinite(state["q"]))
    client.close()


def test_set_ne_to_ee_is_reflected_and_moves_o_t_ee(serve):
    server = serve()
    client = RawClient(server.host)
    client.connect()
    before = client.state()
    _, wire, after = client.shift_ee_along_z(0.1)
    np.testing.assert_allclose(after["F_T_EE"], wire, atol=1e-7)
    # the flange z axis points down at home: the EE frame is 0.1 m lower
    assert after["O_T_EE"][14] == pytest.approx(before["O_T_EE"][14] - 0.1, abs=1e-4)
    client.close()
