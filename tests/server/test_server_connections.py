"""Who holds the robot (docs/socket.md): the client that completed a valid Connect.
A reconnect right after a disconnect is never refused; connections that never send
a Connect are closed after 2 s and can never lock a client out (the hand's alike)."""

from __future__ import annotations

import socket
import struct
import time

import pytest

from franka_sim_gym.fci.wire import protocol as p
from franka_sim_gym.server.client_slot import MAX_UNCONNECTED
from franka_sim_gym.server.connection import CONNECT_TIMEOUT_S
from tests.raw_client import RawClient
from tests.server.test_server_bad_input import wait_for_log

pytestmark = pytest.mark.socket

GRIPPER_HEADER = struct.Struct("<HII")


def test_a_hundred_immediate_reconnects_are_never_refused(serve):
    server = serve("--no-gripper")
    refused = []
    for k in range(100):
        client = RawClient(server.host)
        try:
            assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
            client.state()
        except (ConnectionError, OSError) as exc:
            refused.append(f"{k}: {exc}")
        finally:
            client.close()
    assert refused == [], refused
    assert "refusing" not in server.log()


def idle_connections(host: str, port: int, count: int) -> list[socket.socket]:
    """``count`` connections that send two bytes of a header and then nothing."""
    socks = []
    for _ in range(count):
        sock = socket.create_connection((host, port), timeout=5)
        sock.sendall(b"\x00\x00")
        socks.append(sock)
    return socks


def closed_by_server(sock: socket.socket, timeout: float) -> bool:
    sock.settimeout(timeout)
    try:
        return sock.recv(64) == b""
    except ConnectionError:
        return True
    except TimeoutError:
        return False


def test_idle_connections_cannot_lock_the_robot_out_and_are_closed(serve):
    server = serve("--no-gripper")
    idle = idle_connections(server.host, 1337, 20)
    start = time.monotonic()
    client = RawClient(server.host)
    assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
    client.state()
    assert time.monotonic() - start < CONNECT_TIMEOUT_S  # not only once they are gone
    # Beyond MAX_UNCONNECTED the oldest were closed at once; the rest after the timeout.
    assert all(closed_by_server(s, 0.5) for s in idle[: 20 - MAX_UNCONNECTED])
    assert all(closed_by_server(s, CONNECT_TIMEOUT_S + 2) for s in idle[20 - MAX_UNCONNECTED :])
    wait_for_log(server, f"sent no valid Connect within {CONNECT_TIMEOUT_S:g} s: connection closed")
    assert f"more than {MAX_UNCONNECTED} connections have not sent a Connect" in server.log()
    # The connected client was served throughout and still is.
    before = int(client.latest_state()["message_id"])
    time.sleep(0.1)
    assert int(client.latest_state()["message_id"]) > before + 50
    for sock in idle:
        sock.close()
    client.close()


def test_idle_connections_cannot_lock_the_hand_out(serve):
    server = serve()
    idle = idle_connections(server.host, 1338, 20)
    with socket.create_connection((server.host, 1338), timeout=5) as sock:
        sock.sendall(GRIPPER_HEADER.pack(0, 1, 14) + struct.pack("<HH", 3, 5555))
        assert sock.recv(14) == GRIPPER_HEADER.pack(0, 1, 14) + struct.pack("<HH", 0, 3)
    assert all(closed_by_server(s, CONNECT_TIMEOUT_S + 2) for s in idle)
    wait_for_log(server, "gripper client")
    assert "sent no valid Connect within" in server.log()
    for sock in idle:
        sock.close()
