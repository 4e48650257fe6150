"""A request before Connect is answered with its own command's kCommandNotPossibleRejected
(libfranka common/include/research_interface/robot/service_types.h: Move's is 5, every
other command's 1) and nothing else: GetRobotModel returns no URDF (docs/robot-state.md)."""

from __future__ import annotations

import pytest

from franka_sim_gym.fci.wire import protocol as p
from franka_sim_gym.server.testing import start_server
from tests.raw_client import RawClient
from tests.server.test_server_bad_input import wait_for_log
from tests.server.test_server_commands import VALID_REQUESTS

pytestmark = pytest.mark.socket

REQUESTS = {
    **VALID_REQUESTS,
    p.Command.kMove: p.MoveRequest(
        0, 0, p.DEFAULT_DEVIATION, p.DEFAULT_DEVIATION, False, (0.0,) * 7
    ),
}
EXPECTED = {
    p.Command.kMove: 5,  # Move::Status::kCommandNotPossibleRejected, not 1 (kMotionStarted)
    **{command: 1 for command in VALID_REQUESTS},
}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """One server for the module: each test connects, and disconnects, once."""
    server = start_server("--no-gripper", log_path=tmp_path_factory.mktemp("serve") / "log")
    yield server
    server.stop()


@pytest.mark.parametrize("command", sorted(REQUESTS), ids=lambda c: c.name)
def test_every_command_before_connect_gets_its_own_not_possible_status(server, command):
    client = RawClient(server.host)
    try:
        command_id = client.request(command, REQUESTS[command].payload())
        reply = client.reply(command_id)
        assert (reply.command, reply.command_id) == (command, command_id)
        assert reply.payload == bytes([EXPECTED[command]]), reply.payload[:40]
        wait_for_log(server, f"{command.name} before Connect: answered kCommandNotPossibleRejected")
        # The same connection then connects and is served.
        assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
        client.state()
    finally:
        client.close()
