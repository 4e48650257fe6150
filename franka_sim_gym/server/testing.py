"""`franka-sim-gym serve` as a child process, for tests and benchmarks of libfranka clients.

libfranka always connects to TCP 1337 (and the hand to 1338), so each server gets
a loopback address of its own in 127.0.0.0/8; :func:`start_server` picks a free
one, starts the server there, waits until it answers Connect and streams a state
(:func:`~franka_sim_gym.server.check.wait_until_ready`) and returns a handle that
reads its log and stops it. The pytest plugin's ``franka_sim`` fixture
(:mod:`franka_sim_gym.server.pytest_plugin`) is this with a teardown.
"""

from __future__ import annotations

import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from ..fci.wire.protocol import COMMAND_PORT
from .check import wait_until_ready
from .gripper_server import GRIPPER_PORT


@dataclass
class SimServer:
    """A running `franka-sim-gym serve` child process."""

    host: str
    process: subprocess.Popen
    log_path: Path
    flags: tuple[str, ...] = field(default_factory=tuple)

    @property
    def address(self) -> tuple[str, int]:
        """(host, 1337): where a libfranka client connects (``Robot(server.host)``)."""
        return self.host, COMMAND_PORT

    def log(self) -> str:
        """Everything the server has logged so far."""
        return self.log_path.read_text(errors="replace")

    def alive(self) -> bool:
        return self.process.poll() is None

    def stop(self, timeout: float = 10.0) -> int:
        """Stop it with Ctrl-C (SIGINT), as a user would; killed if it does not exit."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        return self.process.returncode


def free_loopback_address(rng: random.Random | None = None) -> str:
    """A 127.x.y.z address whose ports 1337 and 1338 nobody is listening on."""
    rng = rng or random.Random()
    for _ in range(100):
        host = f"127.{rng.randrange(64, 255)}.{rng.randrange(0, 256)}.{rng.randrange(1, 255)}"
        try:
            for port in (COMMAND_PORT, GRIPPER_PORT):
                with socket.create_server((host, port)):
                    pass
        except OSError:
            continue
        return host
    raise RuntimeError("no free loopback address found in 127.64.0.0-127.254.255.255")


def _sigint_default() -> None:
    # A background shell job starts with SIGINT ignored, and an ignored signal stays
    # ignored across exec: the server would not stop on Ctrl-C. Restore the default.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_server(
    *flags: str,
    host: str | None = None,
    log_path: Path | None = None,
    env: dict[str, str] | None = None,
    cwd: Path | None = None,
    ready_timeout: float = 60.0,
    attempts: int = 3,
    lockstep: bool = False,
) -> SimServer:
    """Start `python -m franka_sim_gym.server --host HOST FLAGS...` and wait until it is ready.

    Args:
        flags: `serve` flags, e.g. ``"--enforce-motion-limits"``, ``"--no-gripper"``.
        host: the address to bind (default: a free loopback address, retried
            ``attempts`` times if another process takes it first).
        log_path: where its output goes (default: a temporary file).
        env: extra environment variables (e.g. ``FRANKA_SIM_*``).
        cwd: its working directory.
        ready_timeout: how long to wait for Connect and a state [s].
        lockstep: add ``--lockstep`` (motions run as fast as the client answers,
            reproducibly; docs/socket.md) unless ``flags`` has it already.

    Raises:
        RuntimeError: the server exited or did not become ready (its log attached).
    """
    if log_path is None:
        handle, name = tempfile.mkstemp(prefix="franka-sim-", suffix=".log")
        os.close(handle)
        log_path = Path(name)
    if lockstep and "--lockstep" not in flags:
        flags = (*flags, "--lockstep")
    why = ""
    for _ in range(attempts if host is None else 1):
        address = host or free_loopback_address()
        with open(log_path, "w") as log_file:
            process = subprocess.Popen(
                [sys.executable, "-m", "franka_sim_gym.server", "--host", address, *flags],
                cwd=cwd,
                stdout=log_file,
                stderr=subprocess.STDOUT,
                env={**os.environ, **(env or {})},
                preexec_fn=_sigint_default,  # noqa: PLW1509 - only resets a signal
            )
        server = SimServer(address, process, log_path, tuple(flags))
        why = wait_until_ready(address, timeout=ready_timeout, alive=server.alive)
        if why is None:
            return server
        server.stop()
        if "cannot serve" not in server.log():  # not an address clash: do not retry
            break
    raise RuntimeError(f"franka-sim-gym serve {' '.join(flags)} not ready: {why}\n{server.log()}")
