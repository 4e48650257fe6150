"""pylibfranka's default RealtimeConfig::kEnforce on an ordinary kernel: refused by libfranka
itself, and run unchanged through `franka-sim-gym run-client --` (README, "The real-time
kernel check")."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from franka_sim_gym.server import run_client as rc
from tests.conftest import ROOT
from tests.socket_helpers import CLIENTS

pytestmark = pytest.mark.socket


def run(args: list[str]) -> tuple[dict | None, str]:
    proc = subprocess.run(args, capture_output=True, text=True, timeout=120, cwd=ROOT)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    return (json.loads(lines[-1]) if lines else None), proc.stderr


def test_kenforce_is_refused_on_this_kernel_and_runs_through_run_client(serve):
    if rc.kernel_reads_realtime():
        pytest.skip("this kernel reads /sys/kernel/realtime = 1: kEnforce needs no wrapper")
    user_namespace = not rc.has_capability(rc.CAP_SYS_ADMIN)
    problem = rc.namespaces_problem(shutil.which("unshare"), rc.namespace_flags(user_namespace))
    if problem:
        pytest.skip(f"namespaces unavailable on this machine: {problem}")
    server = serve()
    client = [sys.executable, str(CLIENTS / "realtime_client.py"), "enforced", server.host]
    direct, _ = run(client)
    assert direct["exception_type"] == "RealtimeException", direct
    if rc.scheduling_problem(user_namespace) is None:
        # (SCHED_FIFO is granted: libfranka's first check passes, the kernel check was it)
        assert "Running kernel does not have realtime capabilities" in direct["exception"]
    wrapped, stderr = run(
        [sys.executable, "-m", "franka_sim_gym.server.cli", "run-client", "--", *client]
    )
    if rc.scheduling_problem(user_namespace) is None:
        assert wrapped == {"mode": "Idle", "errors": "[]"}, (wrapped, stderr)
    else:  # the wrapper said why, and libfranka failed on the scheduling right, not the kernel
        assert "real-time scheduling" in stderr
        assert wrapped["exception_type"] == "RealtimeException", wrapped
        assert "unable to set realtime scheduling" in wrapped["exception"]
