"""The README's main job: serve the simulated FR3 and move it with a real libfranka client.

Starts `franka-sim-gym serve` on a loopback address, runs
examples/pylibfranka_joint_motion.py against it, and stops the server.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from franka_sim_gym.server.testing import free_loopback_address

HERE = Path(__file__).resolve().parent
HOST = "127.0.0.1"


def port_free(host: str, port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex((host, port)) != 0


def main() -> int:
    # libfranka always connects to port 1337: where it is taken, another loopback address.
    host = HOST if port_free(HOST, 1337) and port_free(HOST, 1338) else free_loopback_address()
    print(f"starting franka-sim-gym serve on {host}:1337")
    server = subprocess.Popen([sys.executable, "-m", "franka_sim_gym.server", "--host", host])
    try:
        deadline = time.monotonic() + 30
        while port_free(host, 1337):
            if server.poll() is not None or time.monotonic() > deadline:
                print("the server did not start", file=sys.stderr)
                return 1
            time.sleep(0.1)
        time.sleep(0.2)
        result = subprocess.run(
            [sys.executable, str(HERE / "pylibfranka_joint_motion.py"), "--host", host],
            timeout=120,
        )
        return result.returncode
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=10)


if __name__ == "__main__":
    sys.exit(main())
