"""native.require: an extension whose rules have no other text is there and current, or
importing its caller is an ImportError saying why and how to build it; every C source is
built and required."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

import franka_sim_gym
from franka_sim_gym import native


@pytest.fixture
def kernels(tmp_path, monkeypatch):
    """A folder searched as part of the franka_sim_gym package: write kernels into it."""
    monkeypatch.setattr(franka_sim_gym, "__path__", [*franka_sim_gym.__path__, str(tmp_path)])
    return tmp_path


@pytest.mark.parametrize(
    ("name", "source", "why"),
    [
        ("_req_missing", None, "No module named"),
        ("_req_broken", "raise ImportError('undefined symbol: PyFoo')", "undefined symbol: PyFoo"),
        ("_req_older", "def rule(): pass", "has no detail (a stale build"),
    ],
)
def test_a_required_extension_missing_broken_or_stale_is_an_import_error_saying_how_to_build(
    kernels, name, source, why
):
    if source is not None:
        (kernels / f"{name}.py").write_text(source + "\n")
    with pytest.raises(ImportError) as caught:
        native.require(name, "rule", "detail")
    assert why in str(caught.value)
    assert "have no other text" in str(caught.value) and "C compiler" in str(caught.value)


def test_a_current_extension_loads(kernels):
    (kernels / "_req_good.py").write_text("def rule(): pass\ndef detail(): pass\n")
    assert native.require("_req_good", "rule", "detail").rule() is None


def test_every_c_source_is_a_required_extension_and_imports():
    """setup.py builds every ``<layer>/_<name>.c``; each is in native.REQUIRED and imports
    (no switch, no optional kernel left to fall back from)."""
    root = Path(franka_sim_gym.__file__).parent
    sources = {".".join(p.relative_to(root).with_suffix("").parts) for p in root.rglob("_*.c")}
    assert sources == set(native.REQUIRED)
    for name in native.REQUIRED:
        importlib.import_module(f"franka_sim_gym.{name}")
