"""A client that stops reading its TCP replies never holds up the robot (docs/socket.md):
the state stream keeps its 1 kHz, the motion ends as the robot ends it, the client is
dropped once past the outbox's bound, and the next client connects."""

from __future__ import annotations

import socket
import struct
import time

import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.tables import MAX_LOST_CYCLES
from franka_sim_gym.fci.wire import RobotMode
from franka_sim_gym.fci.wire import protocol as p
from franka_sim_gym.server.outbox import MAX_OUTBOX_BYTES
from tests.raw_client import RawClient
from tests.server.test_server_bad_input import wait_for_log

pytestmark = pytest.mark.socket

#: GetRobotModel replies (10 kB each) to leave unread: several MB, far more than the
#: kernel buffers hold, less than the outbox's byte bound (so the time bound drops it).
UNREAD_REQUESTS = 600


def read_until_closed(sock: socket.socket, timeout: float) -> bool:
    """Read (and discard) until the server ends the connection; False if it does not."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sock.settimeout(max(0.01, deadline - time.monotonic()))
        try:
            if not sock.recv(1 << 20):
                return True
        except ConnectionError:
            return True
        except TimeoutError:
            return False
    return False


def test_a_client_that_stops_reading_gets_its_reflex_on_time_and_is_dropped(serve):
    server = serve("--enforce-comm-constraints", "--no-gripper")
    client = RawClient(server.host, receive_buffer=4096)
    assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
    move, state = client.start_joint_position_move()
    q = state["q_d"].astype(float)
    client.hold(q, 20)
    # Building 600 replies holds the server busy a while on a loaded machine (at a load
    # of 10 the stream paused over a second): wait for states longer than usual.
    client.udp.settimeout(5.0)
    for _ in range(UNREAD_REQUESTS):  # replies never read from here on
        client.request(p.Command.kGetRobotModel)
    answered = int(client.hold(q, 100)["message_id"])  # the replies back up meanwhile
    # ... then the client stops commanding: the communication-constraints reflex is
    # due 20 cycles later, and the state stream must not wait for the unread replies.
    # Judged in the robot's own count (message ids), so a loaded machine's slower
    # clock does not matter: read until the stream ends (the client dropped).
    states = []
    client.udp.settimeout(2.0)
    while True:
        try:
            states.append(client.state())
        except TimeoutError:
            break
    ids = [int(s["message_id"]) for s in states]
    reflex = next(s for s in states if s["robot_mode"] == RobotMode.kReflex)
    assert reflex["errors"][Error.communication_constraints_violation]
    # The 20th unanswered state is the last of the motion (fci/accounting.py): the next
    # one shows the reflex. Late, it would be the waiting replies' doing.
    assert int(reflex["message_id"]) - answered == MAX_LOST_CYCLES + 1, (answered, ids[:30])
    # The robot ran on while the replies waited: from the client's last answer to its
    # drop a reply waits MAX_REPLY_DELAY_S (1,000 cycles at 1 kHz; 640 at the 0.64x real
    # time of a load of 8). A tick thread that waited on the replies ran none of them.
    assert ids[-1] - answered > 250, (answered, ids[-1])
    # Past the bound the server drops the client (and logs why) and goes on ticking.
    wait_for_log(server, "does not read its replies (a reply undelivered for 1 s)", timeout=5)
    assert read_until_closed(client.tcp, timeout=5)
    assert "motion ended: kReflexAborted" in server.log()
    client.close()
    assert UNREAD_REQUESTS * 10_000 < MAX_OUTBOX_BYTES  # the time bound, not the bytes
    # The next client connects and the robot's stream runs on: 100 cycles more.
    second = RawClient(server.host)
    assert second.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
    ids = [int(second.state()["message_id"])]
    while ids[-1] - ids[0] < 100:
        ids.append(int(second.state()["message_id"]))  # a stalled stream: TimeoutError
    second.close()


GRIPPER_HEADER = struct.Struct("<HII")
#: GripperState's message id (docs/wire-protocol.md §10.3).
GRIPPER_STATE = struct.Struct("<I")


def test_a_gripper_client_that_stops_reading_never_holds_up_the_hand(serve):
    server = serve()
    tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    tcp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    tcp.settimeout(5.0)
    tcp.connect((server.host, 1338))
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind((tcp.getsockname()[0], 0))
    udp.settimeout(1.0)
    tcp.sendall(GRIPPER_HEADER.pack(0, 0, 14) + struct.pack("<HH", 3, udp.getsockname()[1]))
    assert tcp.recv(14)[-4:] == struct.pack("<HH", 0, 3)
    udp.recv(64)
    # Stop requests, answered by the hand's timer thread; their replies are never read.
    stop = b"".join(GRIPPER_HEADER.pack(4, k, 10) for k in range(1, 40_001))
    tcp.sendall(stop)
    # GripperState goes out at 60 Hz throughout, counted by its message ids until the
    # stream ends (the client dropped once a reply waited 1 s: ~60 broadcasts).
    ids = []
    udp.settimeout(2.0)
    while True:
        try:
            ids.append(GRIPPER_STATE.unpack_from(udp.recv(64))[0])
        except TimeoutError:
            break
    assert ids[-1] - ids[0] > 20, ids
    wait_for_log(server, "does not read its replies", timeout=5)
    assert read_until_closed(tcp, timeout=5)
    tcp.close()
    udp.close()
    with socket.create_connection((server.host, 1338), timeout=5) as again:
        again.sendall(GRIPPER_HEADER.pack(0, 0, 14) + struct.pack("<HH", 3, 5555))
        assert again.recv(14)[-4:] == struct.pack("<HH", 0, 3)
