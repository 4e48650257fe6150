"""A real pylibfranka client through the connection rules of docs/socket.md: a Robot
recreated at once is never refused, idle connections never lock it out."""

from __future__ import annotations

import pytest

from tests.server.test_server_connections import idle_connections

pytestmark = pytest.mark.socket


def test_a_hundred_robots_made_one_after_another_all_connect(serve, client):
    server = serve("--no-gripper")
    result = client(
        "pylibfranka", "reconnect_loop", server.host, timeout=120, env={"RECONNECTS": "100"}
    )
    assert result == {"refused": []}, result
    assert "refusing" not in server.log()


def test_twenty_idle_connections_do_not_keep_pylibfranka_out(serve, client):
    server = serve()
    idle = idle_connections(server.host, 1337, 20) + idle_connections(server.host, 1338, 20)
    try:
        robot = client("pylibfranka", "read_once", server.host, timeout=30)
        hand = client("gripper", "connect_only", server.host, timeout=30)
    finally:
        for sock in idle:
            sock.close()
    assert "first" in robot, robot
    assert hand["error"] is None, hand
