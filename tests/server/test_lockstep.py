"""`serve --lockstep` (docs/socket.md "Lockstep"): the flag and its variables, the wait for
an answer (server/lockstep.py), requests during the wait, the 1 kHz stream outside
motions, and the CI helpers against a lockstep server."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

from franka_sim_gym.fci.wire import MotionGeneratorMode
from franka_sim_gym.fci.wire import protocol as p
from franka_sim_gym.server.cli import build_parser, lockstep_options
from franka_sim_gym.server.lockstep import DEFAULT_TIMEOUT_S, AnswerWait
from tests.raw_client import RawClient

CLI = [sys.executable, "-m", "franka_sim_gym.server.cli"]


# -- the flag and its environment variables -------------------------------------------------


def test_lockstep_is_off_by_default_and_waits_50_ms(monkeypatch):
    monkeypatch.delenv("FRANKA_SIM_LOCKSTEP", raising=False)
    monkeypatch.delenv("FRANKA_SIM_LOCKSTEP_TIMEOUT", raising=False)
    args = build_parser().parse_args(["serve"])
    assert lockstep_options(args.lockstep, args.lockstep_timeout) == (False, 0.05)
    assert DEFAULT_TIMEOUT_S == 0.05


def test_the_variables_set_lockstep_and_the_flags_win(monkeypatch):
    monkeypatch.setenv("FRANKA_SIM_LOCKSTEP", "1")
    monkeypatch.setenv("FRANKA_SIM_LOCKSTEP_TIMEOUT", "20")
    args = build_parser().parse_args(["serve"])
    assert lockstep_options(args.lockstep, args.lockstep_timeout) == (True, 0.02)
    args = build_parser().parse_args(["serve", "--lockstep", "--lockstep-timeout", "5"])
    assert lockstep_options(args.lockstep, args.lockstep_timeout) == (True, 0.005)
    monkeypatch.setenv("FRANKA_SIM_LOCKSTEP", "0")
    args = build_parser().parse_args(["serve"])
    assert lockstep_options(args.lockstep, args.lockstep_timeout)[0] is False


@pytest.mark.parametrize(
    ("flags", "env", "message"),
    [
        (["--lockstep-timeout", "0"], {}, "--lockstep-timeout 0.0: expected more than 0"),
        (["--lockstep-timeout", "nan"], {}, "--lockstep-timeout nan: expected more than 0"),
        (["--lockstep-timeout", "1000"], {}, "libfranka gives up on a state after 1 s"),
        ([], {"FRANKA_SIM_LOCKSTEP_TIMEOUT": "soon"}, "FRANKA_SIM_LOCKSTEP_TIMEOUT='soon' is not"),
    ],
)
def test_a_bad_timeout_is_refused_with_exit_2(flags, env, message):
    run = subprocess.run(
        [*CLI, "serve", "--host", "127.0.0.1", "--lockstep", *flags],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, **env},
    )
    assert run.returncode == 2
    assert message in run.stderr


# -- the wait ---------------------------------------------------------------------------------


@pytest.fixture
def udp_pair():
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    server.setblocking(False)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield server, sender
    server.close()
    sender.close()


def drain(sock: socket.socket, got: list[bytes]) -> None:
    try:
        while True:
            got.append(sock.recv(4096))
    except BlockingIOError:
        pass


def test_the_wait_ends_when_the_answer_arrives(udp_pair):
    server, sender = udp_pair
    wait = AnswerWait(server.fileno(), timeout=5.0)
    got: list[bytes] = []
    threading.Timer(
        0.05, lambda: [sender.sendto(m, server.getsockname()) for m in (b"late", b"fresh")]
    ).start()
    start = time.monotonic()
    answered = wait.wait(
        lambda: True, lambda: b"fresh" in got, lambda: drain(server, got), lambda: None
    )
    assert answered is True
    assert time.monotonic() - start < 2.5  # not the 5 s bound
    assert wait.take_times().answered == 1
    wait.close()


def test_a_wait_without_an_answer_lasts_its_bound(udp_pair):
    server, sender = udp_pair
    wait = AnswerWait(server.fileno(), timeout=0.03)
    got: list[bytes] = []
    sender.sendto(b"not an answer", server.getsockname())
    start = time.monotonic()
    answered = wait.wait(lambda: True, lambda: False, lambda: drain(server, got), lambda: None)
    assert answered is False
    assert time.monotonic() - start >= 0.03
    assert got == [b"not an answer"]  # what came was handed over all the same
    assert wait.take_times().answered == 0
    wait.close()


def test_a_request_is_applied_during_the_wait_and_can_end_it(udp_pair):
    server, _ = udp_pair
    wait = AnswerWait(server.fileno(), timeout=5.0)
    motion = {"running": True}

    def apply_requests() -> None:
        motion["running"] = False  # e.g. StopMove

    threading.Timer(0.05, wait.notify).start()
    start = time.monotonic()
    answered = wait.wait(lambda: motion["running"], lambda: False, lambda: None, apply_requests)
    assert answered is False and motion["running"] is False
    assert time.monotonic() - start < 2.5
    wait.close()


def test_a_timeout_must_be_positive(udp_pair):
    with pytest.raises(ValueError, match="lockstep timeout must be > 0 s"):
        AnswerWait(udp_pair[0].fileno(), timeout=0.0)


# -- a lockstep server ------------------------------------------------------------------------


@pytest.mark.socket
def test_outside_a_motion_the_stream_keeps_1_khz(serve):
    server = serve("--lockstep", "--no-gripper")
    client = RawClient(server.host)
    client.connect()
    first = client.state()
    start = time.monotonic()
    while time.monotonic() - start < 0.5:
        last = client.state()
    elapsed_ms = (time.monotonic() - start) * 1000.0
    advanced = int(last["message_id"]) - int(first["message_id"])
    assert advanced <= elapsed_ms + 20, (advanced, elapsed_ms)  # 1 state a ms, not faster
    assert advanced >= 100  # and it streams
    client.close()


def queued_states(client: RawClient) -> list[bytes]:
    """The state datagrams that arrived and were not read yet."""
    got: list[bytes] = []
    client.udp.setblocking(False)
    try:
        drain(client.udp, got)
    finally:
        client.udp.settimeout(1.0)
    return got


@pytest.mark.socket
def test_stop_move_during_a_wait_is_answered_without_waiting_out_the_bound(serve):
    """A motion nobody answers waits 900 ms per state here; StopMove still ends it at once."""
    server = serve("--lockstep", "--lockstep-timeout", "900", "--no-gripper")
    client = RawClient(server.host)
    client.connect()
    client.state()
    move = client.request(
        p.Command.kMove,
        p.MoveRequest(0, 0, p.DEFAULT_DEVIATION, p.DEFAULT_DEVIATION, False, (0.0,) * 7).payload(),
    )
    assert client.reply(move).payload[0] == p.MoveStatus.kMotionStarted
    state = client.state()
    while state["motion_generator_mode"] != MotionGeneratorMode.kJointPosition:
        state = client.state()
    # Answer one state so the wait is for a running motion's command, then go quiet.
    client.send_command(message_id=int(state["message_id"]), q_c=state["q"])
    time.sleep(0.1)
    # The answer released one cycle, whose state now waits: no 1 kHz stream meanwhile.
    assert 1 <= len(queued_states(client)) <= 2
    start = time.monotonic()
    stop = client.request(p.Command.kStopMove)
    assert client.reply(stop, timeout=10).payload[0] == p.StopMoveStatus.kSuccess
    assert client.reply(move, timeout=10).payload[0] == p.MoveStatus.kPreempted
    # Not when the 900 ms wait runs out (>= 0.8 s from here): no count tells the two apart
    # (the stop ends the motion at its one cycle either way, none lost), so a bound that
    # holds at a load of 8 judges it: two small replies, not a wait.
    assert time.monotonic() - start < 0.6
    after = client.latest_state()
    assert after["robot_mode"] == 1 and np.all(np.isfinite(after["q"]))
    client.close()


@pytest.mark.socket
def test_check_is_ready_against_a_lockstep_server(serve):
    server = serve("--lockstep", "--no-gripper")
    check = subprocess.run(
        [*CLI, "check", server.host, "--timeout", "30"], capture_output=True, text=True, timeout=60
    )
    assert check.returncode == 0, check.stderr
    assert "lockstep during motions, 50 ms for an answer" in server.log()


@pytest.mark.socket
def test_the_plugin_option_serves_every_fixture_in_lockstep(tmp_path):
    (tmp_path / "test_user.py").write_text(
        textwrap.dedent(
            """
            def test_my_controller(franka_sim):
                assert "clock: lockstep during motions" in franka_sim.log()
            """
        )
    )
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "--franka-sim-lockstep",
            str(tmp_path),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "1 passed" in run.stdout
