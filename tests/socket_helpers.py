"""What the socket tests share: real clients in child processes, reading a server's log,
and the fixtures ``serve`` and ``client`` (tests/e2e/conftest.py and
tests/server/conftest.py import them for their folders).

Servers come from the ``franka_sim_factory`` fixture of the project's own pytest
plugin (:mod:`franka_sim_gym.server.pytest_plugin`), each on a loopback address of
its own (libfranka always connects to TCP 1337); libfranka has no reply timeout,
so every client runs in a child process under a hard timeout.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable

import pytest

from franka_sim_gym.fci.tables import MAX_LOST_CYCLES
from franka_sim_gym.server.testing import SimServer
from tests.conftest import ROOT

CLIENTS = ROOT / "tests" / "e2e" / "clients"


def motion_summaries(log: str) -> list[tuple[str, int, int]]:
    """(status, lost cycles, longest lost run) of every motion a server logged as ended."""
    pattern = r"motion ended: (\w+) after \d+ cycles; lost (\d+) \(longest run (\d+)\)"
    return [(m[1], int(m[2]), int(m[3])) for m in re.finditer(pattern, log)]


def recovery_cycles(log: str) -> int:
    """The cycles the one AutomaticErrorRecovery a server logged waited for standstill."""
    [cycles] = re.findall(r"recovery answered after (\d+) cycles", log)
    return int(cycles)


def unstarved(
    serve, run: Callable[[SimServer], dict], *flags: str, attempts: int = 3
) -> tuple[SimServer, dict]:
    """Serve FLAGS and run one client against it; repeat when the machine starved the client.

    With aborting off (the default) a client that a loaded machine stalls is not
    stopped: the robot extrapolates (holds, from 20 cycles on), and the client then
    resumes from its own trajectory with a jump, which a tracking or arrival
    assertion would misread as a controller fault. The server's own account decides:
    an attempt with a lost run of 20, or with lost cycles and a motion-limit
    violation logged (the resumed stream's discontinuity: CI saw a 1.6 cm tracking
    error after a run of 16), proves nothing about tracking and is repeated; any
    other is returned (the server stopped) for the test to judge.
    """
    for _attempt in range(attempts):
        server = serve(*flags)
        result = run(server)
        server.stop()
        log = server.log()
        summaries = motion_summaries(log)
        starved = any(longest >= MAX_LOST_CYCLES for *_, longest in summaries)
        jumped = any(lost for _, lost, _ in summaries) and "motion limit violated" in log
        if not (starved or jumped):
            return server, result
    pytest.fail(f"{attempts} attempts starved the client (see unstarved): too loaded")


def run_client(
    kind: str, scenario: str, host: str, timeout: float = 60.0, env: dict | None = None
) -> dict:
    """Run one client scenario in a child process; its last stdout line is JSON."""
    script = CLIENTS / f"{kind}_client.py"
    proc = subprocess.run(
        [sys.executable, str(script), scenario, host],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
        env={**os.environ, **(env or {})},
    )
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    if not lines:
        raise AssertionError(
            f"{kind} scenario {scenario} printed no result (exit {proc.returncode})\n"
            f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
        )
    return json.loads(lines[-1])


class HeldClient:
    """A client scenario that holds its connection until released (the 'first client' of
    a second-client test; tests/e2e/clients/scenario_main.py hold_until_told)."""

    def __init__(self, kind: str, scenario: str, host: str, timeout: float = 60.0) -> None:
        self.process = subprocess.Popen(
            [sys.executable, str(CLIENTS / f"{kind}_client.py"), scenario, host],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=ROOT,
        )
        line = self.process.stdout.readline()  # once a state came, or the result on failure
        if line.strip() != "holding":
            self.process.kill()
            raise AssertionError(f"{kind} {scenario} did not hold a connection: {line!r}")
        self.timeout = timeout

    def release(self) -> dict:
        """Tell it to stop holding; its result (JSON)."""
        out, _ = self.process.communicate("release\n", timeout=self.timeout)
        return json.loads(out.strip().splitlines()[-1])


@pytest.fixture
def serve(franka_sim_factory):
    """``serve(*flags, env=None)``: a ready `franka-sim-gym serve` on its own loopback
    address (the plugin's ``franka_sim_factory``), stopped after the test."""
    return franka_sim_factory


@pytest.fixture
def client():
    """``client(kind, scenario, host)``: a real client scenario in a child process."""
    return run_client
