"""`franka-sim-gym check HOST`: wait until a robot server answers Connect and streams a state.

The readiness gate for a CI job that starts `franka-sim-gym serve` in the
background: it does what libfranka's Robot does first (Connect, then one
RobotState over UDP: libfranka src/robot_impl.cpp) and disconnects. It works
against any FCI v10 server, this one or a robot.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

from ..fci.wire import ROBOT_STATE_SIZE
from ..fci.wire import protocol as p


def probe(host: str, port: int = p.COMMAND_PORT, timeout: float = 1.0) -> str | None:
    """One attempt: None when Connect succeeded and a state arrived, else why not."""
    try:
        tcp = socket.create_connection((host, port), timeout=timeout)
    except OSError as exc:
        return f"no TCP connection to {host}:{port} ({exc})"
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        # States go to (the TCP peer's address, udp_port), as libfranka expects.
        udp.bind((tcp.getsockname()[0], 0))
        udp.settimeout(timeout)
        tcp.sendall(p.encode_connect_request(0, udp.getsockname()[1], p.VERSION))
        decoder = p.FrameDecoder()
        frames: list = []
        while not frames:
            data = tcp.recv(4096)
            if not data:
                return "the server closed the connection before answering Connect"
            frames = [f for f in decoder.feed(data) if isinstance(f, p.Frame)]
        status, version = p.decode_connect_reply(frames[0].payload)
        if status != p.ConnectStatus.kSuccess:
            return f"Connect answered status {status} (server version {version})"
        while True:
            data = udp.recv(4096)
            if len(data) == ROBOT_STATE_SIZE:
                return None
    except (OSError, p.ProtocolError) as exc:  # socket.timeout is an OSError
        return f"no Connect reply and state from {host}:{port} ({exc or type(exc).__name__})"
    finally:
        udp.close()
        tcp.close()


def wait_until_ready(
    host: str,
    port: int = p.COMMAND_PORT,
    timeout: float = 30.0,
    alive: Callable[[], bool] | None = None,
) -> str | None:
    """Probe until the server is ready (None) or ``timeout`` [s] passes (the last reason).

    ``alive``, if given, is asked between attempts (a server process that exited
    will not come up: the wait ends at once).
    """
    deadline = time.monotonic() + timeout
    while True:
        why = probe(host, port, timeout=min(1.0, max(0.05, deadline - time.monotonic())))
        if why is None:
            return None
        if alive is not None and not alive():
            return f"the server exited ({why})"
        if time.monotonic() >= deadline:
            return why
        time.sleep(0.05)
