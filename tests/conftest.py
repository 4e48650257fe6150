"""What every test folder shares: the repository root, its examples and scripts.

The socket tests' helpers and fixtures are in tests/socket_helpers.py (the fixtures
imported by tests/e2e/conftest.py and tests/server/conftest.py).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# The servers are stopped with Ctrl-C (SIGINT) and must exit cleanly. A shell starts a
# background job (`make test &`, nohup) with SIGINT ignored, and an ignored signal stays
# ignored in every child: each server would then sit out stop()'s 10 s and be killed.
# A handled signal is reset to its default in the children, where Python turns it into
# KeyboardInterrupt again.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def load_example(name: str):
    """examples/NAME.py as a module (the examples import each other as siblings, so
    examples/ goes on the path once and each loads under its own name, once)."""
    import importlib

    examples = str(ROOT / "examples")
    if examples not in sys.path:
        sys.path.insert(0, examples)
    return importlib.import_module(name)


def run_python(script: Path, *args: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """Run a script of this repository in a child process (the repository on its path)."""
    return subprocess.run(
        [sys.executable, str(script), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
