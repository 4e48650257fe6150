"""The CI helpers (docs/socket.md): the pytest plugin's franka_sim fixture, installed
with the package, and `franka-sim-gym check HOST`, the readiness gate."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import pytest

from franka_sim_gym.fci.wire import protocol as p
from franka_sim_gym.server.testing import free_loopback_address
from tests.raw_client import RawClient

pytestmark = pytest.mark.socket

CLI = [sys.executable, "-m", "franka_sim_gym.server.cli"]


@pytest.mark.franka_sim("--no-gripper", "--enforce-motion-limits")
def test_franka_sim_serves_with_the_marker_flags_and_is_ready(franka_sim):
    client = RawClient(franka_sim.host)  # ready: no waiting, no retry
    assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
    client.state()
    client.close()
    assert franka_sim.address == (franka_sim.host, 1337)
    assert "enforce motion limits: True" in franka_sim.log()
    assert "Franka Hand" not in franka_sim.log()  # --no-gripper


def test_a_project_without_our_conftest_gets_the_fixture(tmp_path):
    """What `pip install franka-sim-gym` gives any project: the fixture, by the entry point."""
    (tmp_path / "test_user.py").write_text(
        textwrap.dedent(
            """
            import socket

            import pytest


            @pytest.mark.franka_sim("--no-gripper")
            def test_my_controller(franka_sim):
                with socket.create_connection(franka_sim.address, timeout=5):
                    pass
                assert franka_sim.alive() and "serving FR3" in franka_sim.log()
            """
        )
    )
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "1 passed" in run.stdout


def test_check_waits_for_a_server_started_in_the_background(tmp_path):
    host = free_loopback_address()
    with open(tmp_path / "serve.log", "w") as log:
        server = subprocess.Popen(
            [*CLI, "serve", "--host", host, "--no-gripper"], stdout=log, stderr=subprocess.STDOUT
        )
    try:
        check = subprocess.run(
            [*CLI, "check", host, "--timeout", "60"], capture_output=True, text=True, timeout=90
        )
        assert check.returncode == 0, check.stderr
        assert "is ready (Connect answered, state received)" in check.stdout
        # Ready means ready: a client connects at once.
        client = RawClient(host)
        assert client.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
        client.state()
        client.close()
    finally:
        server.terminate()
        server.wait(timeout=10)


def test_check_times_out_with_exit_1_when_nothing_serves():
    host = free_loopback_address()
    start = time.monotonic()
    check = subprocess.run(
        [*CLI, "check", host, "--timeout", "1"], capture_output=True, text=True, timeout=30
    )
    assert check.returncode == 1
    assert time.monotonic() - start < 15
    assert f"{host}:1337 not ready after 1 s" in check.stderr


def test_serve_help_shows_the_check_and_the_fixture():
    out = subprocess.run([*CLI, "serve", "--help"], capture_output=True, text=True).stdout
    assert "franka-sim-gym check 127.0.0.2" in out
    assert "def test_my_controller(franka_sim)" in out
    assert "@pytest.mark.franka_sim(" in out
