"""examples/train_rllib.py on a Ray cluster of two nodes on this machine's loopback: a
head started on 127.0.0.1 (Ray names it by the machine's own address) and a worker node
on 127.0.0.2 (``ray start --head`` / ``ray start --address``, one CPU each), the recipe
pointed at the head with ``--address``, one runner on each node (docs/scaling.md,
"Beyond one machine"). Skipped where Ray is not installed.

The nodes are this test's own: each ``ray start --block`` runs in its own process group
with its own temp dir and a token of its own (``RAY_AUTH_TOKEN``, not the user's
``~/.ray``), and is stopped by signalling that group, never by ``ray stop``, which stops
every Ray process of the machine, other people's clusters too.
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack, contextmanager
from pathlib import Path

import pytest

from tests.conftest import ROOT

pytest.importorskip("ray.rllib")

HEAD, WORKER = "127.0.0.1", "127.0.0.2"
LAST = re.compile(
    r"^rllib: env_id=FrankaFCICartesianVelocity-v0 runners=2 envs_per_runner=2 "
    r"env_steps_per_s=(\d+) episode_return_mean=(-?\d+\.\d+)$"
)
#: what ``ray start --block`` prints once its node is up
STARTED = "This command will now block forever"


def free_port(host: str) -> int:
    """A TCP port free on ``host`` now (the kernel's pick)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def ray_command() -> list[str]:
    """Ray's CLI of this Python (``ray`` beside it, else the module it runs)."""
    script = Path(sys.executable).parent / "ray"
    return [str(script)] if script.exists() else [sys.executable, "-m", "ray.scripts.scripts"]


def ray_processes_of(group: int) -> list[int]:
    """The live processes of a process group (from /proc: a Linux test)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if os.getpgid(int(entry.name)) == group:
                    pids.append(int(entry.name))
            except ProcessLookupError:
                pass
    return pids


@contextmanager
def ray_node(args: list[str], env: dict, log: Path, timeout: float = 180.0):
    """One ``ray start --block`` node in a process group of its own; on exit SIGTERM to
    the group, SIGKILL to what is left after 30 s. Yields the ``ray start`` process (its
    pid is the group's) once the node is up."""
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [*ray_command(), "start", "--block", *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
        )
    try:
        deadline = time.monotonic() + timeout
        while STARTED not in log.read_text():
            if proc.poll() is not None:
                pytest.fail(f"ray start exited with {proc.returncode}:\n{log.read_text()[-3000:]}")
            if time.monotonic() > deadline:
                pytest.fail(f"ray start not up within {timeout:.0f} s:\n{log.read_text()[-3000:]}")
            time.sleep(0.5)
        yield proc
    finally:
        stop_group(proc)


def stop_group(proc: subprocess.Popen) -> None:
    """Stop every process of ``proc``'s group (the node's GCS, raylet, workers...)."""
    group = proc.pid  # start_new_session: the group is the leader's pid
    for sig, wait in ((signal.SIGTERM, 30.0), (signal.SIGKILL, 10.0)):
        try:
            os.killpg(group, sig)
        except ProcessLookupError:
            break
        deadline = time.monotonic() + wait
        while ray_processes_of(group) and time.monotonic() < deadline:
            proc.poll()  # reap the leader
            time.sleep(0.5)
        if not ray_processes_of(group):
            break
    proc.poll()


def test_a_head_and_a_worker_node_on_loopback_each_serve_a_runner(tmp_path):
    # short temp dirs: Ray's Unix sockets live under them (108 bytes a path at most)
    temp = Path(tempfile.mkdtemp(prefix="fsg-ray-"))
    port = free_port(HEAD)
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        # token authentication (Ray 2.60's default for ray start) with a token of its own
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN": secrets.token_hex(32),
        "RAY_worker_niceness": "0",  # runners at this test's niceness (docs/scaling.md)
        "RAY_USAGE_STATS_ENABLED": "0",
    }
    common = ["--num-cpus=1", "--disable-usage-stats"]
    try:
        with ExitStack() as stack:
            head = stack.enter_context(
                ray_node(
                    ["--head", f"--node-ip-address={HEAD}", f"--port={port}"]
                    + [f"--temp-dir={temp / 'head'}", "--include-dashboard=false", *common],
                    env,
                    tmp_path / "head.log",
                )
            )
            worker = stack.enter_context(
                ray_node(
                    [f"--address={HEAD}:{port}", f"--node-ip-address={WORKER}"]
                    + [f"--temp-dir={temp / 'worker'}", *common],
                    env,
                    tmp_path / "worker.log",
                )
            )
            out = tmp_path / "rllib"
            args = ["--address", f"{HEAD}:{port}", "--runners", "2", "--envs-per-runner", "2"]
            args += ["--iterations", "1", "--batch-size", "160", "--episodes", "3"]
            args += ["--seed", "1", "--out", str(out)]
            args += ["--env-kwargs", '{"max_episode_steps": 10}']
            proc = subprocess.run(
                [sys.executable, str(ROOT / "examples" / "train_rllib.py"), *args],
                capture_output=True,
                text=True,
                timeout=600,
                cwd=ROOT,
                env=env,
            )
            assert proc.returncode == 0, proc.stderr[-3000:]
            lines = proc.stdout.strip().splitlines()
            match = LAST.match(lines[-1])
            assert match, lines[-3:]
            assert int(match.group(1)) > 0
            # 160 env steps of 10-step episodes over 4 arms: every arm ended episodes
            assert -11.0 <= float(match.group(2)) <= 0.0
            # One CPU a node and one a runner: a runner on each node. Ray names the head
            # by the machine's own address (it resolves 127.0.0.1 to it: the head's log
            # says "Local node IP"), the worker node by 127.0.0.2.
            placed = [line for line in lines if line.startswith("env runners on nodes: ")]
            assert len(placed) == 1, lines
            nodes = placed[0].removeprefix("env runners on nodes: ").split(", ")
            head_ip = re.search(r"Local node IP: (\S+)", (tmp_path / "head.log").read_text())
            assert head_ip, (tmp_path / "head.log").read_text()[-2000:]
            head_ip = head_ip.group(1)
            assert sorted(nodes) == sorted([head_ip, WORKER]), (nodes, head_ip)
            assert (out / "checkpoint").is_dir()
            assert any(line.startswith("evaluate: success_rate=") for line in lines)
        # both nodes stopped: nothing left of either process group
        assert ray_processes_of(head.pid) == [] and ray_processes_of(worker.pid) == []
    finally:
        shutil.rmtree(temp, ignore_errors=True)
