"""examples/train_bc.py end to end: the ensemble it saves and loads back, and its
learning curve (``--curve``). The behaviour cloning it runs is tested in
test_sb3_demos.py."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("minari")
pytest.importorskip("stable_baselines3")

from franka_sim_gym.training.datasets import record  # noqa: E402
from tests.conftest import load_example  # noqa: E402
from tests.training.test_datasets import REFLEXES  # noqa: E402
from tests.training.test_sb3_demos import Smooth, one_thread  # noqa: E402, F401


def test_train_bc_saves_an_ensemble_that_evaluate_and_where_it_fails_read(
    datasets_dir, tmp_path, monkeypatch, capsys
):
    from franka_sim_gym.training import evaluation
    from franka_sim_gym.training.ensemble import Ensemble

    record("tests/bc-v0", "FrankaFCI-v0", Smooth(), 3, env_kwargs=REFLEXES, num_envs=3)
    out = tmp_path / "bc"
    argv = ["train_bc.py", "--demos", "tests/bc-v0", "--steps", "20", "--net", "16"]
    monkeypatch.setattr("sys.argv", [*argv, "--ensemble", "0", "--out", str(out)])
    with pytest.raises(SystemExit):
        load_example("train_bc").main()
    assert "--ensemble 0: an ensemble has at least one member" in capsys.readouterr().err
    argv += ["--ensemble", "2", "--eval-episodes", "2", "--out", str(out)]
    monkeypatch.setattr("sys.argv", argv)
    evaluated = []  # what train_bc.py evaluates: the ensemble, not its first member
    real_evaluate = evaluation.evaluate
    monkeypatch.setattr(
        evaluation,
        "evaluate",
        lambda policy, *a, **k: evaluated.append(policy) or real_evaluate(policy, *a, **k),
    )
    load_example("train_bc").main()
    assert isinstance(evaluated[0].model, Ensemble) and len(evaluated[0].model.members) == 2
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("bc: success_rate=")
    model, config = load_example("evaluate").load_model(out / "model.zip")
    assert config == {"algo": "sac", "env_id": "FrankaFCI-v0", "env_kwargs": REFLEXES}
    # two members from two seeds behind the dataset's normalisation (the reach's raw
    # features), acting on the mean of their actions
    ensemble = model.model
    assert isinstance(ensemble, Ensemble) and len(ensemble.members) == 2
    env = gym.make("FrankaFCI-v0", **REFLEXES)
    obs, _ = env.reset(seed=3)
    env.close()
    seen = model.normalization.normalize_obs(obs)
    first, second = (m.predict(seen, deterministic=True)[0] for m in ensemble.members)
    assert not np.array_equal(first, second)
    np.testing.assert_array_equal(model.predict(obs)[0], np.mean([first, second], axis=0))
    alone, _ = load_example("evaluate").load_model(out / "model_member1.zip")
    np.testing.assert_array_equal(alone.predict(obs, deterministic=True)[0], second)
    rows = load_example("where_it_fails").run(model, "FrankaFCI-v0", REFLEXES, 3, seed=0)
    assert len(rows) == 3 and {r["end"] for r in rows} <= {"success", "reflex", "time limit"}
    for row in rows:
        assert (row["end"] == "reflex") == ("errors" in row) and row["step"] <= 6


def test_train_bc_curve_evaluates_the_actors_of_each_step_and_keeps_the_final_policy(
    datasets_dir, tmp_path, monkeypatch, capsys
):
    import csv

    from franka_sim_gym.training import evaluation

    record("tests/curve-v0", "FrankaFCI-v0", Smooth(), 3, env_kwargs=REFLEXES, num_envs=3)
    env = gym.make("FrankaFCI-v0", **REFLEXES)
    obs, _ = env.reset(seed=3)
    env.close()
    argv = ["train_bc.py", "--demos", "tests/curve-v0", "--net", "16", "--ensemble", "2"]
    argv += ["--eval-episodes", "2"]
    monkeypatch.setattr("sys.argv", [*argv, "--steps", "20", "--curve", "30"])
    with pytest.raises(SystemExit):
        load_example("train_bc").main()
    assert "--curve 30: evaluate every 1 to --steps (20) steps" in capsys.readouterr().err
    seen = []  # the evaluated policy's action on one observation, at each evaluation
    real_evaluate = evaluation.evaluate

    def evaluate(policy, *args, **kwargs):
        seen.append(policy.predict(obs, deterministic=True)[0])
        return real_evaluate(policy, *args, **kwargs)

    monkeypatch.setattr(evaluation, "evaluate", evaluate)
    runs = {}
    for name, extra in (
        ("curve", ["--steps", "20", "--curve", "10"]),
        ("at10", ["--steps", "10"]),
        ("at20", ["--steps", "20"]),
    ):
        seen.clear()
        monkeypatch.setattr("sys.argv", [*argv, *extra, "--out", str(tmp_path / name)])
        load_example("train_bc").main()
        runs[name] = (list(seen), capsys.readouterr().out.strip().splitlines()[-1])
    # the curve evaluated the members as they were after 10 and after 20 steps ...
    (at_10, at_20), _ = runs["curve"]
    np.testing.assert_array_equal(at_10, runs["at10"][0][0])
    np.testing.assert_array_equal(at_20, runs["at20"][0][0])
    assert not np.array_equal(at_10, at_20)
    # ... and saved the final policy, the same as without the curve
    saved, _ = load_example("evaluate").load_model(tmp_path / "curve" / "model.zip")
    np.testing.assert_array_equal(saved.predict(obs)[0], at_20)
    with open(tmp_path / "curve" / "curve.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["steps"]) for r in rows] == [10, 20]
    assert 0 <= float(rows[0]["wall_s"]) <= float(rows[1]["wall_s"])
    last = rows[-1]
    final = runs["at20"][1]  # bc: success_rate=x reflex_rate=y wall_s=z
    assert f"success_rate={float(last['success_rate']):.3f}" in final
    assert f"reflex_rate={float(last['reflex_rate']):.3f}" in final
    assert isinstance(json.loads(last["reflexes_by_error"]), dict)
    assert not (tmp_path / "at20" / "curve.csv").exists()
