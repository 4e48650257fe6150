"""Every benchmarks/*.py runs as documented, in its short mode (``--smoke``: every row
of its table, ~a second of measuring; benchmarks/smoke.py), so a benchmark the code has
outgrown turns `make test` red. The figures a smoke run prints are not judged: speed is
measured by the full runs (benchmarks/RESULTS.md)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

from tests.conftest import ROOT

BENCHMARKS = sorted(
    path for path in (ROOT / "benchmarks").glob("*.py") if path.name != "smoke.py"
)
#: What a benchmark needs beyond the test extra (it is skipped, naming it, without).
NEEDS = {"rllib_scaling.py": "ray"}


def runnable(name: str) -> bool:
    needed = NEEDS.get(name)
    return needed is None or importlib.util.find_spec(needed) is not None


def smoke(path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(path), "--smoke"],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )


@pytest.fixture(scope="module")
def runs(request) -> dict[str, subprocess.CompletedProcess]:
    """The smoke run of every selected, runnable benchmark, two at a time (most of each
    is the interpreter importing MuJoCo, torch or pylibfranka: two cores, half the wait)."""
    selected = {
        item.callspec.params["path"]
        for item in request.session.items
        if item.originalname == "test_the_benchmark_runs_its_short_mode"
    }
    paths = [path for path in BENCHMARKS if path in selected and runnable(path.name)]
    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(zip((p.name for p in paths), pool.map(smoke, paths), strict=True))


def test_every_benchmark_is_run():
    assert len(BENCHMARKS) >= 10  # cycle_cpu ... task_rate: none lost to a bad glob


@pytest.mark.parametrize("path", BENCHMARKS, ids=[path.name for path in BENCHMARKS])
def test_the_benchmark_runs_its_short_mode(path, runs):
    if not runnable(path.name):
        pytest.skip(f"{path.name} needs {NEEDS[path.name]} (the rllib extra)")
    proc = runs[path.name]
    assert proc.returncode == 0, (proc.stdout[-2000:], proc.stderr[-3000:])
    table = [line for line in proc.stdout.splitlines() if line.strip()]
    assert len(table) >= 3, proc.stdout  # a header and rows
    assert "nan" not in proc.stdout.lower().split(), proc.stdout
