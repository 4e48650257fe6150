"""native.load: a kernel that was not built is the documented numpy fallback, silently; one
that is there but broken or stale is logged with the reason before the fallback."""

from __future__ import annotations

import logging

import pytest

import franka_sim_gym
from franka_sim_gym import native


@pytest.fixture
def kernels(tmp_path, monkeypatch):
    """A folder searched as part of the franka_sim_gym package: write kernels into it."""
    monkeypatch.setattr(franka_sim_gym, "__path__", [*franka_sim_gym.__path__, str(tmp_path)])
    monkeypatch.setattr(native, "ENABLED", True)
    return tmp_path


@pytest.mark.parametrize(
    ("name", "source", "why"),
    [
        ("_test_broken", "raise ImportError('undefined symbol: PyFoo')", "undefined symbol: PyFoo"),
        ("_test_needs", "import franka_sim_gym_no_such_module", "franka_sim_gym_no_such_module"),
        ("_test_stale", "DELTA_T = 0.002", "built for a cycle of 0.002 s, not 0.001 s"),
    ],
)
def test_a_kernel_that_is_there_but_unusable_is_logged_with_the_reason(
    kernels, caplog, name, source, why
):
    (kernels / f"{name}.py").write_text(source + "\n")
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.native"):
        assert native.load(name) is None
    assert f"C kernel {name} not loaded (numpy path taken)" in caplog.text
    assert why in caplog.text


def test_a_kernel_not_built_is_the_numpy_path_without_a_word(kernels, caplog):
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.native"):
        assert native.load("_test_not_built") is None
    assert caplog.text == ""


def test_a_good_kernel_loads(kernels):
    (kernels / "_test_good.py").write_text("DELTA_T = 0.001\n")
    assert native.load("_test_good").DELTA_T == native.CYCLE


# -- native.require: an extension whose rules have no other text ----------------------------


@pytest.mark.parametrize(
    ("name", "source", "why"),
    [
        ("_req_missing", None, "No module named"),
        ("_req_broken", "raise ImportError('undefined symbol: PyFoo')", "undefined symbol: PyFoo"),
        ("_req_stale", "DELTA_T = 0.002", "built for a cycle of 0.002 s, not 0.001 s"),
        ("_req_older", "DELTA_T = 0.001\ndef rule(): pass", "has no detail (a stale build"),
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


def test_a_required_extension_loads_whatever_the_switch_says(kernels, monkeypatch):
    (kernels / "_req_good.py").write_text("DELTA_T = 0.001\n")
    monkeypatch.setattr(native, "ENABLED", False)  # FRANKA_SIM_GYM_NATIVE=0
    assert native.load("_req_good") is None
    assert native.require("_req_good").DELTA_T == native.CYCLE
