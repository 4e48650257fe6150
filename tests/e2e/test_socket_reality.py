"""`serve --reality` with real clients (issue 37, docs/reality.md): a pylibfranka client at
rest sees its torque sensors fluctuate and the estimate offset by the robot's model error,
with no contact flag; libfranka's joint_impedance_control logic reads a torque error of
friction and noise; two servers of the same seed publish the same states, other seeds
others."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest

from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE, ROBOT_STATE_SIZE
from tests.raw_client import RawClient

pytestmark = pytest.mark.socket


def test_a_pylibfranka_client_sees_the_fr3_profile(serve, client):
    """At rest: tau_J's standard deviation over 1 s within 0.002-0.5 Nm on some joint, the
    external force off by 0.2-5 N, no contact flag. The joint impedance example's torque
    error (tau_d + gravity - tau_J): 0.01-2 Nm RMS, of it the friction compensation."""
    server = serve("--reality", "fr3", "--reality-seed", "1", "--lockstep", "--no-gripper")
    rest = client("reality", "rest", server.host)
    assert "exception" not in rest, rest
    assert rest["samples"] > 500
    assert 0.002 <= max(rest["tau_J_std"]) <= 0.5, rest["tau_J_std"]
    assert 0.2 <= rest["F_norm"] <= 5.0, rest["F_mean"]
    assert not rest["contact"]
    impedance = client("reality", "joint_impedance", server.host)
    assert impedance.get("error", "exception") is None, impedance
    assert impedance["cycles"] > 2500
    # issue 37's window is 0.01-2 Nm; the robot's friction compensation at the circle's
    # speeds puts it at ~0.2 (docs/reality.md), the ideal robot at ~0.008
    assert 0.1 <= impedance["rms"] <= 2.0, impedance
    assert not impedance["contact"]
    server.stop()
    log = server.log()
    assert 'reality: {"profile":"fr3","seed":1,' in log


def record(host: str, until: threading.Event, states: dict[int, bytes]) -> None:
    """Every state a server streams to a connected raw client, by message id, until
    ``until`` is set."""
    c = RawClient(host)
    c.udp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    c.connect()
    try:
        while not until.is_set():
            data = c.udp.recv(4096)
            if len(data) == ROBOT_STATE_SIZE:
                states[int(np.frombuffer(data, ROBOT_STATE_DTYPE)["message_id"][0])] = data
    finally:
        c.close()


def same_ids(hosts: list[str], overlap: int = 200, timeout: float = 30.0) -> list[dict]:
    """The servers' states, recorded together until every pair shares ``overlap`` message
    ids (servers started one after the other publish the same ids at different times)."""
    stop = threading.Event()
    recorded = [{} for _ in hosts]
    threads = [
        threading.Thread(target=record, args=(h, stop, r), daemon=True)
        for h, r in zip(hosts, recorded, strict=True)
    ]
    for t in threads:
        t.start()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        time.sleep(0.2)
        ids = [set(r) for r in list(recorded)]
        if all(ids) and len(set.intersection(*ids)) >= overlap:
            break
    stop.set()
    for t in threads:
        t.join(timeout=5)
    return recorded


def test_two_servers_of_one_seed_publish_the_same_states_and_other_seeds_others(serve):
    """Under randomized, seed 3 twice and seed 4: the states of equal message ids are the
    same bytes for the same seed (the drawn robot and its sensors' noise), other bytes for
    the other seed."""
    flags = ("--reality", "randomized", "--no-gripper")
    servers = [serve(*flags, "--reality-seed", s) for s in ("3", "3", "4")]
    a, b, c = same_ids([s.host for s in servers])
    for server in servers:
        server.stop()
    common = sorted(set(a) & set(b) & set(c))
    assert len(common) >= 200, (len(a), len(b), len(c))
    assert all(a[k] == b[k] for k in common)
    assert not any(a[k] == c[k] for k in common)
    logs = [s.log() for s in servers]
    assert [log.count('reality: {"profile":"randomized"') for log in logs] == [1, 1, 1]
