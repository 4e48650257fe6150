"""franka_sim_gym.training's place: nothing below it imports it, and its evaluation needs
no learning framework."""

from __future__ import annotations

import ast
import subprocess
import sys

from tests.conftest import ROOT

LOWER = ("fci", "sim", "envs", "server")


def imported_modules(path) -> set[str]:
    """Every module a file imports, relative imports resolved against its package."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            module = ".".join(p for p in (base, node.module or "") if p)
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


def test_no_lower_package_imports_training():
    offenders = [
        str(path.relative_to(ROOT))
        for layer in LOWER
        for path in (ROOT / "franka_sim_gym" / layer).rglob("*.py")
        if any(m.startswith("franka_sim_gym.training") for m in imported_modules(path))
    ]
    assert offenders == []


def test_the_evaluation_imports_no_learning_framework():
    code = (
        "import sys, franka_sim_gym.training.evaluation; "
        "print(sorted(m for m in ('stable_baselines3', 'torch', 'ray') if m in sys.modules))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
