"""`serve --reality PROFILE --reality-seed N` (and FRANKA_SIM_REALITY /
FRANKA_SIM_REALITY_SEED): the served robot's draw, the flag winning over its variable, a bad
profile or seed refused with exit 2 and its reason."""

from __future__ import annotations

import subprocess
import sys

import pytest

from franka_sim_gym.reality import draw, load_profile
from franka_sim_gym.server.cli import build_parser, reality_draw

CLI = [sys.executable, "-m", "franka_sim_gym.server.cli"]


def served(argv, monkeypatch, env=None):
    for name in ("FRANKA_SIM_REALITY", "FRANKA_SIM_REALITY_SEED"):
        monkeypatch.delenv(name, raising=False)
    for name, value in (env or {}).items():
        monkeypatch.setenv(name, value)
    args = build_parser().parse_args(["serve", *argv])
    return reality_draw(args.reality, args.reality_seed)


def test_the_ideal_robot_by_default(monkeypatch):
    assert served([], monkeypatch) is None
    assert served(["--reality", "ideal", "--reality-seed", "4"], monkeypatch) is None


def test_the_flags_draw_the_robot(monkeypatch):
    got = served(["--reality", "randomized", "--reality-seed", "4"], monkeypatch)
    assert got == draw(load_profile("randomized"), 4)
    assert served(["--reality", "fr3"], monkeypatch).seed == 0  # the default seed


def test_the_variables_draw_it_and_the_flags_win(monkeypatch):
    env = {"FRANKA_SIM_REALITY": "randomized", "FRANKA_SIM_REALITY_SEED": "9"}
    assert served([], monkeypatch, env) == draw(load_profile("randomized"), 9)
    got = served(["--reality", "fr3", "--reality-seed", "2"], monkeypatch, env)
    assert got == draw(load_profile("fr3"), 2)


@pytest.mark.parametrize(
    ("flags", "env", "message"),
    [
        (["--reality", "mars"], {}, "reality profile 'mars': neither a shipped profile"),
        (["--reality", "fr3", "--reality-seed", "-1"], {}, "--reality-seed -1: expected"),
        ([], {"FRANKA_SIM_REALITY_SEED": "soon"}, "FRANKA_SIM_REALITY_SEED='soon' is not"),
        ([], {"FRANKA_SIM_REALITY": "fr3 "}, None),  # whitespace around a name is fine
    ],
)
def test_a_bad_profile_or_seed_is_a_value_error_naming_it(flags, env, message, monkeypatch):
    if message is None:
        assert served(flags, monkeypatch, env).profile == "fr3"
        return
    with pytest.raises(ValueError) as error:
        served(flags, monkeypatch, env)
    assert message in str(error.value)


def test_serve_refuses_a_bad_profile_file_with_exit_2_naming_its_entry(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text('{"model": {"mass_scale": -1}}')
    run = subprocess.run(
        [*CLI, "serve", "--host", "127.0.0.1", "--no-gripper", "--reality", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 2
    assert "model.mass_scale must be > 0" in run.stderr
