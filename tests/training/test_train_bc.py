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


#: Push, short: two noise-injected episodes of the solver (examples/scripted.py)
PUSH = {"max_episode_steps": 6}


@pytest.fixture(scope="module")
def small_demos(datasets_dir):
    """Two Push demonstrations ("tests/pushd-v0") and one Reach episode on a joint
    interface ("tests/reachd-v0"), for the flags that take one and refuse the other."""
    solver = load_example("scripted").ScriptedPolicy("FrankaFCIPush-v0", env_kwargs=PUSH)
    record("tests/pushd-v0", "FrankaFCIPush-v0", solver, 2, 0, PUSH, noise=0.1)
    record("tests/reachd-v0", "FrankaFCI-v0", Smooth(), 1, env_kwargs=REFLEXES, num_envs=1)
    return solver


def test_train_bc_dagger_rounds_act_with_the_last_policy_and_refit_on_every_round(
    small_demos, tmp_path, monkeypatch, capsys
):
    import csv

    import minari

    from franka_sim_gym.training import evaluation, sb3_demos
    from franka_sim_gym.training.datasets import DEMONSTRATOR_ACTION, episode_seed

    solver = small_demos
    argv = ["train_bc.py", "--demos", "tests/pushd-v0", "--steps", "20", "--net", "16"]
    argv += ["--eval-episodes", "2", "--out", str(tmp_path / "dagger")]
    reach = [*argv[:2], "tests/reachd-v0", *argv[3:]]
    for bad, message in (
        ([*argv, "--dagger", "-1"], "--dagger -1 --dagger-episodes 10: rounds >= 0, episodes >= 1"),
        ([*argv, "--dagger", "1", "--curve", "10"], "--dagger and --curve: give one"),
        ([*argv, "--dagger-id", "tests/mine-v0"], "--dagger-id names the DAgger rounds'"),
        ([*reach, "--dagger", "1"], "--dagger: no scripted solver labels FrankaFCI-v0"),
        (
            [*argv, "--dagger", "1", "--dagger-episodes", "9999"],
            "--dagger: the rounds' episode seeds (2 on) would reach the evaluation's (10000 on)",
        ),
    ):
        monkeypatch.setattr("sys.argv", bad)
        with pytest.raises(SystemExit):
            load_example("train_bc").main()
        assert message in capsys.readouterr().err
    fitted_on, evaluated = [], []  # what each fit saw; each round's evaluated policy
    real_cloning, real_evaluate = sb3_demos.behaviour_cloning, evaluation.evaluate

    def cloning(policy, demos, *args, **kwargs):
        fitted_on.append([d.id for d in demos])
        return real_cloning(policy, demos, *args, **kwargs)

    def evaluate(policy, *args, **kwargs):
        evaluated.append(policy)
        return real_evaluate(policy, *args, **kwargs)

    monkeypatch.setattr(sb3_demos, "behaviour_cloning", cloning)
    monkeypatch.setattr(evaluation, "evaluate", evaluate)
    monkeypatch.setattr("sys.argv", [*argv, "--dagger", "2", "--dagger-episodes", "2"])
    load_example("train_bc").main()
    out = capsys.readouterr().out.strip().splitlines()
    rounds = ["tests/pushd-dagger-seed0-r1-v0", "tests/pushd-dagger-seed0-r2-v0"]
    # each fit from scratch on the demonstrations and every round so far
    assert fitted_on == [
        ["tests/pushd-v0"],
        ["tests/pushd-v0", rounds[0]],
        ["tests/pushd-v0", *rounds],
    ]
    for r, dataset_id in enumerate(rounds):
        dataset = minari.load_dataset(dataset_id)
        # the episode seeds go on from the demonstrations' (0, 1)
        assert [episode_seed(dataset, k) for k in range(2)] == [2 + 2 * r, 3 + 2 * r]
        for episode in dataset.iterate_episodes():
            steps = len(episode)
            obs = {k: v[:steps] for k, v in episode.observations.items()}
            # the policy of the round before acted (up to the rounding of a batch's products)
            acted = np.stack(
                [
                    evaluated[r].predict(
                        {k: v[t : t + 1] for k, v in obs.items()}, deterministic=True
                    )[0][0]
                    for t in range(steps)
                ]
            )
            np.testing.assert_allclose(episode.actions, acted, rtol=0, atol=1e-6)
            # ... and the solver, following the episode, labelled each state
            solver.reset(np.arange(1))
            labels = [solver({k: v[t : t + 1] for k, v in obs.items()})[0] for t in range(steps)]
            np.testing.assert_array_equal(episode.infos[DEMONSTRATOR_ACTION][1:], labels)
    with open(tmp_path / "dagger" / "dagger.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(int(r["round"]), int(r["labelled_episodes"])) for r in rows] == [
        (0, 2),
        (1, 4),
        (2, 6),
    ]
    assert f"success_rate={float(rows[-1]['success_rate']):.3f}" in out[-1]
    assert "2 demonstrations and 2 DAgger rounds" in out[-3]
    # an existing round's dataset is refused by name, before anything is fitted again
    fitted_on.clear()
    monkeypatch.setattr("sys.argv", [*argv, "--dagger", "1", "--dagger-episodes", "2"])
    with pytest.raises(SystemExit):
        load_example("train_bc").main()
    assert "--dagger: dataset 'tests/pushd-dagger-seed0-r1-v0' exists" in capsys.readouterr().err
    assert fitted_on == []


def test_train_bc_combine_upward_is_saved_and_loaded_back(
    small_demos, tmp_path, monkeypatch, capsys
):
    from franka_sim_gym.training.ensemble import Ensemble
    from franka_sim_gym.training.governor import FLOOR, JOINT_4, ElbowGovernor
    from franka_sim_gym.training.sb3_zoo import NormalizedPolicy

    out = tmp_path / "upward"
    argv = ["train_bc.py", "--steps", "20", "--net", "16", "--eval-episodes", "2"]
    argv += ["--combine", "upward", "--out", str(out)]
    for bad, message in (
        (["--demos", "tests/pushd-v0"], "--combine upward combines members: give --ensemble 2"),
        (
            ["--demos", "tests/reachd-v0", "--ensemble", "2"],
            "--combine upward acts on a Cartesian velocity's entries: FrankaFCI-v0 has "
            "action_interface 'joint_position'",
        ),
        (
            [
                "--demos",
                "tests/reachd-v0",
                "--ensemble",
                "2",
                "--combine",
                "mean",
                "--elbow-governor",
            ],
            "--elbow-governor acts on a Cartesian velocity's entries: FrankaFCI-v0 has",
        ),
    ):
        monkeypatch.setattr("sys.argv", [*argv, *bad])
        with pytest.raises(SystemExit):
            load_example("train_bc").main()
        assert message in capsys.readouterr().err
    monkeypatch.setattr("sys.argv", [*argv, "--demos", "tests/pushd-v0", "--ensemble", "2"])
    load_example("train_bc").main()
    assert json.loads((out / "train_config.json").read_text())["combine"] == "upward"
    model, _ = load_example("evaluate").load_model(out / "model.zip")
    assert isinstance(model, Ensemble) and model.combine == "upward"
    # with the elbow governor: saved, and loaded back around the ensemble
    governed = tmp_path / "governed"
    monkeypatch.setattr(
        "sys.argv",
        [
            *argv[:-1],
            str(governed),
            "--demos",
            "tests/pushd-v0",
            "--ensemble",
            "2",
            "--elbow-governor",
        ],
    )
    load_example("train_bc").main()
    assert json.loads((governed / "train_config.json").read_text())["governor"] == "elbow"
    loaded, _ = load_example("evaluate").load_model(governed / "model.zip")
    assert isinstance(loaded, ElbowGovernor) and loaded.policy.combine == "upward"
    env = gym.make("FrankaFCIPush-v0", **PUSH)
    obs, _ = env.reset(seed=3)
    env.close()
    batch = {k: v[None] for k, v in obs.items()}
    members = np.stack([m.predict(batch, deterministic=True)[0][0] for m in model.members])
    assert np.ptp(members[:, 2]) > 0  # the members disagree: upward is not the mean
    expected = members.mean(axis=0)
    expected[2] = members[:, 2].max()
    np.testing.assert_allclose(model.predict(batch)[0][0], expected, atol=1e-7)
    # behind the raw features' normalisation, the governor reads the raw joint angles
    raw = tmp_path / "raw"
    monkeypatch.setattr(
        "sys.argv",
        ["train_bc.py", "--steps", "20", "--net", "16", "--eval-episodes", "2", "--out", str(raw)]
        + ["--demos", "tests/pushd-v0", "--features", "raw", "--elbow-governor"],
    )
    load_example("train_bc").main()
    loaded, _ = load_example("evaluate").load_model(raw / "model.zip")
    assert isinstance(loaded, ElbowGovernor) and isinstance(loaded.policy, NormalizedPolicy)
    folded = {k: v[None].copy() for k, v in obs.items()}
    folded["observation"][0, JOINT_4] = -3.0  # past the governor's stop
    seen, cap = [], loaded.cap
    loaded.cap = lambda q4: seen.append(np.array(q4)) or cap(q4)
    toward = loaded.policy.predict(folded, deterministic=True)[0][0, 0]
    assert loaded.predict(folded)[0][0, 0] == max(toward, -FLOOR)
    np.testing.assert_array_equal(seen[0], [-3.0])  # the raw angle, not a normalised one


def test_train_bc_goal_hold_is_saved_loaded_back_outermost_and_refused_by_name(
    small_demos, tmp_path, monkeypatch, capsys
):
    from franka_sim_gym.training import evaluation
    from franka_sim_gym.training.goal_hold import GoalHold
    from franka_sim_gym.training.governor import ElbowGovernor

    out = tmp_path / "held"
    argv = ["train_bc.py", "--steps", "20", "--net", "16", "--eval-episodes", "2"]
    argv += ["--out", str(out)]
    for bad, message in (
        (
            ["--demos", "tests/reachd-v0", "--goal-hold", "0.03"],
            "--goal-hold acts on a Cartesian velocity's entries: FrankaFCI-v0 has "
            "action_interface 'joint_position'",
        ),
        (["--demos", "tests/pushd-v0", "--goal-hold", "0"], "--goal-hold 0.0: radius must be a"),
        (["--demos", "tests/pushd-v0", "--goal-hold", "nan"], "--goal-hold nan: radius must be a"),
    ):
        monkeypatch.setattr("sys.argv", [*argv, *bad])
        with pytest.raises(SystemExit):
            load_example("train_bc").main()
        assert message in capsys.readouterr().err
    evaluated = []
    real = evaluation.evaluate
    monkeypatch.setattr(
        evaluation,
        "evaluate",
        lambda policy, *a, **k: evaluated.append(policy) or real(policy, *a, **k),
    )
    monkeypatch.setattr(
        "sys.argv",
        [*argv, "--demos", "tests/pushd-v0", "--elbow-governor", "--goal-hold", "0.03"],
    )
    load_example("train_bc").main()
    config = json.loads((out / "train_config.json").read_text())
    assert config["goal_hold"] == {"radius": 0.03, "velocity_dims": 3}  # Push's 3-D twist
    for policy in (evaluated[0], load_example("evaluate").load_model(out / "model.zip")[0]):
        assert isinstance(policy, GoalHold) and isinstance(policy.policy, ElbowGovernor)
        assert (policy.radius, policy.velocity_dims) == (0.03, 3)


def test_train_bc_features_line_fits_in_the_line_frame_and_acts_through_it(
    small_demos, tmp_path, monkeypatch, capsys
):
    from franka_sim_gym.training import evaluation, sb3_demos
    from franka_sim_gym.training.ensemble import Ensemble
    from franka_sim_gym.training.governor import ElbowGovernor
    from franka_sim_gym.training.line_frame import LineFrame, to_line_frame, turn_actions

    out = tmp_path / "line"
    argv = ["train_bc.py", "--steps", "20", "--net", "16", "--eval-episodes", "2"]
    argv += ["--out", str(out)]
    monkeypatch.setattr("sys.argv", [*argv, "--demos", "tests/reachd-v0", "--features", "line"])
    with pytest.raises(SystemExit):
        load_example("train_bc").main()
    message = "--features line acts on a Cartesian velocity's entries: FrankaFCI-v0 has"
    assert message in capsys.readouterr().err
    # labels the actor cannot reach in the frame (the box's corner turned): refused
    # before any fit, with nothing written
    corner = lambda obs: np.tile(np.float32([1, 1, 0]), (len(obs["observation"]), 1))  # noqa: E731
    record("tests/pushcorner-v0", "FrankaFCIPush-v0", corner, 1, 0, PUSH, num_envs=1)
    monkeypatch.setattr("sys.argv", [*argv, "--demos", "tests/pushcorner-v0", "--features", "line"])
    with pytest.raises(SystemExit):
        load_example("train_bc").main()
    assert "--features line: " in (err := capsys.readouterr().err) and "actions leave" in err
    assert not out.exists()
    fitted = []  # what the members are fitted on: the demonstrations, turned
    real_cloning = sb3_demos.behaviour_cloning

    def spy(policy, demos, *args, prepare=None, **kwargs):
        obs, actions = sb3_demos.demo_arrays(demos)
        fitted.append((obs, actions, prepare(obs, actions)))
        return real_cloning(policy, demos, *args, prepare=prepare, **kwargs)

    monkeypatch.setattr(sb3_demos, "behaviour_cloning", spy)
    evaluated = []  # what train_bc.py evaluates: the ensemble in the line frame, governed
    real_evaluate = evaluation.evaluate
    monkeypatch.setattr(
        evaluation,
        "evaluate",
        lambda policy, *a, **k: evaluated.append(policy) or real_evaluate(policy, *a, **k),
    )
    argv += ["--demos", "tests/pushd-v0", "--features", "line"]
    monkeypatch.setattr("sys.argv", [*argv, "--ensemble", "2", "--elbow-governor"])
    load_example("train_bc").main()
    assert len(fitted) == 2
    assert isinstance(evaluated[0], ElbowGovernor) and isinstance(evaluated[0].policy, LineFrame)
    obs, actions, (seen, labels) = fitted[0]
    # fitted in the line's frame: every goal straight ahead of its block, and the labels
    # the demonstrated velocities at their lengths, turned by the same angles
    o = seen["observation"]
    np.testing.assert_allclose(seen["desired_goal"][:, 1] - o[:, -13 + 1], 0.0, atol=1e-9)
    assert (seen["desired_goal"][:, 0] - o[:, -13] > 0).all()
    np.testing.assert_allclose(
        np.linalg.norm(labels[:, :2], axis=1), np.linalg.norm(actions[:, :2], axis=1), atol=1e-6
    )
    np.testing.assert_array_equal(labels[:, 2], actions[:, 2])  # the height's: not turned
    assert not np.allclose(labels, actions)
    assert json.loads((out / "train_config.json").read_text())["frame"] == "line"
    loaded, _ = load_example("evaluate").load_model(out)
    assert isinstance(loaded, ElbowGovernor) and isinstance(loaded.policy, LineFrame)
    assert isinstance(loaded.policy.policy, Ensemble)
    # the task frame's statistics are the line frame's: the goal straight ahead of the
    # block, never across (entries 3:6 are the goal from the object)
    member = loaded.policy.policy.members[0]
    extractor = member.policy.actor.features_extractor
    mean = extractor.mean.numpy()
    assert abs(mean[4]) < 1e-6 and mean[3] > 0.01
    # and joint 4's angle last (the elbow's fold), with the demonstrations' statistics
    assert extractor.elbow and extractor.features_dim == 14
    np.testing.assert_allclose(mean[-1], np.mean(obs["observation"][:, 3]), rtol=0.05)
    # acting: the members' mean on the turned observation, turned back
    env = gym.make("FrankaFCIPush-v0", **PUSH)
    obs, _ = env.reset(seed=3)
    env.close()
    batch = {k: v[None] for k, v in obs.items()}
    inside, _ = to_line_frame(batch)
    inside = {k: v.astype(np.float32) for k, v in inside.items()}
    members = [m.predict(inside, deterministic=True)[0] for m in loaded.policy.policy.members]
    turn = np.array(batch["desired_goal"][:, :2], np.float64) - batch["observation"][:, -13:-11]
    turn /= np.linalg.norm(turn)
    expected = turn_actions(np.mean(members, axis=0), turn, +1.0)
    np.testing.assert_allclose(loaded.policy.predict(batch)[0], expected, atol=1e-6)
