"""A warning that can repeat every cycle is logged once, then as a count about once a
second (franka_sim_gym/fci/log_limit.py): stray datagrams never flood the log."""

from __future__ import annotations

import re

import pytest

from franka_sim_gym.fci.wire import protocol as p
from tests.raw_client import RawClient

pytestmark = pytest.mark.socket

STRAYS = 2000


def test_two_thousand_stray_datagrams_during_a_hold_add_a_few_log_lines(serve):
    server = serve("--no-gripper")
    client = RawClient(server.host)
    assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
    move, state = client.start_joint_position_move()
    q = state["q_d"].astype(float)
    for k in range(STRAYS):
        state = client.hold(q, 1)
        # A stale loop beside the client: ids no state ever carried, from its own port.
        client.send_command(message_id=int(state["message_id"]) + 10**6 + k, q_c=q)
    client.finish(q)
    assert client.reply(move).payload[0] == p.MoveStatus.kSuccess
    log = server.log()
    lines = [line for line in log.splitlines() if "answers no state of the running motion" in line]
    assert 1 <= len(lines) <= 12, "\n".join(lines[:20])
    counted = sum(int(n) for n in re.findall(r"and (\d+) more like it", log))
    # The ones after the last line are counted into the next line of their kind.
    assert len(lines) + counted >= STRAYS // 2
    assert len(log.splitlines()) < 40, log[-3000:]
    client.close()
