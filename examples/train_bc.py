"""Behaviour cloning from a Minari dataset: what the demonstrations alone give.

    python examples/train_bc.py --demos franka/push-v0 --out runs/push_bc

The actor of an SB3 SAC policy (the same networks as examples/train_sb3.py --demos)
fitted to the dataset's actions (mean squared error of its deterministic action,
franka_sim_gym.training.sb3_demos.behaviour_cloning; a noise-injected dataset's
demonstrator actions), on the task-frame features of the observation
(``--features task``: franka_sim_gym.training.task_frame, normalised with the dataset's
statistics) or on the whole base-frame observation behind SB3's VecNormalize with the
dataset's statistics (``--features raw``); the default, ``auto``, is ``task`` for the
tasks with an object under a Cartesian interface and ``raw`` for the rest.
``--features line`` (Cartesian velocity) is the task frame turned about the vertical
into the line from the object to its goal, the actions with it
(franka_sim_gym.training.line_frame: fitted in that frame, acting through ``LineFrame``;
saved in train_config.json as ``frame``), with joint 4's angle among the features (the
elbow's fold: where the solvers slow near the base). Then
evaluated as train_sb3.py evaluates (100 episodes side by side, seeds 10,000 on). The
env id and its arguments are the dataset's (``recover_environment``'s spec). Writes
model.zip (with ``raw``: the normalisation, model/vecnormalize.pkl, where
examples/evaluate.py finds it) and train_config.json to --out; last line
``bc: success_rate=<x> reflex_rate=<y> wall_s=<z>``.

``--ensemble K`` fits K actors, member k from seed ``seed + 10,000 k`` (member 0 is the
single actor of ``--seed``), and evaluates the mean of their actions
(franka_sim_gym.training.ensemble); the members are saved as model.zip and
model_member<k>.zip, listed in train_config.json, and load back as one policy.

``--combine upward`` (Cartesian-velocity ids, with ``--ensemble``) acts on the members'
mean with the vertical velocity of the most upward member (franka_sim_gym.training.ensemble;
saved in train_config.json as ``combine``).

``--elbow-governor`` (Cartesian-velocity ids) caps the policy's velocity toward the base
as joint 4 nears its stop (franka_sim_gym.training.governor; saved as ``governor``).

``--goal-hold RADIUS`` (Cartesian-velocity ids) holds the hand still while the object is
within RADIUS metres of its goal (franka_sim_gym.training.goal_hold; saved as
``goal_hold``): the policy's velocity zeroed, its width kept.

``--curve EVERY`` also evaluates the policy after every EVERY fitting steps (each member
at that step; the same 100 episodes) and writes the learning curve to curve.csv in
--out: fitting steps, the fitting's wall time to that step (all members), the success
and reflex rates and the reflexes by error name (examples/plot_curves.py draws it). The
last row is the final policy; with or without the curve it is the same, bit for bit
(its rates; the wall time, each member's from its construction to its last step, also
counts the curve's copies of the actors).

``--dagger ROUNDS`` goes on after the fit with DAgger (Ross, Gordon and Bagnell, 2011,
"A Reduction of Imitation Learning and Structured Prediction to No-Regret Online
Learning"): each round runs ``--dagger-episodes`` episodes in which the policy as fitted
so far acts and the dataset's scripted solver (examples/scripted.py, following the same
episode) labels every state the policy visits; the round is recorded as a Minari dataset
of its own (``--dagger-id``'s name with ``-r<round>``; the labels are its
``demonstrator_action``) and the members are fitted again, from their seeds, on the
demonstrations and every round so far. Round r's episodes are seeded on from the
demonstrations' last seed. Each round's policy is evaluated (the same 100 episodes) and
the rows written to dagger.csv in --out (round, solver-labelled episodes, the wall time
of every fit so far (not the rounds' recording and evaluations), success and reflex
rates, reflexes by error); the final policy is the last round's (its printed ``wall_s``
the same sum). The features' normalisation is the demonstrations' throughout.
"""

from __future__ import annotations

import argparse
import copy
import csv
import inspect
import json
import time
from pathlib import Path

from franka_sim_gym.training.ensemble import COMBINE
from franka_sim_gym.training.evaluation import EVALUATION_SEED


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--demos", required=True, metavar="DATASET_ID")
    parser.add_argument("--steps", type=int, default=5000, help="gradient steps")
    parser.add_argument("--net", default="256,256", help="hidden layer sizes")
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--features",
        choices=("auto", "task", "line", "raw"),
        default="auto",
        help="task: the task-frame features (object tasks, Cartesian interfaces); line: "
        "the task frame turned into the line from the object to its goal (Cartesian "
        "velocity); raw: the base-frame observation; auto: task where it applies",
    )
    parser.add_argument(
        "--ensemble", type=int, default=1, metavar="K", help="fit K actors, act on their mean"
    )
    parser.add_argument(
        "--combine",
        choices=COMBINE,
        default="mean",
        help="how the members' actions make the ensemble's: their mean, or (upward; "
        "Cartesian velocity) the mean with the most upward member's vertical velocity",
    )
    parser.add_argument(
        "--elbow-governor",
        action="store_true",
        help="(Cartesian velocity) cap the policy's velocity toward the base as joint 4 "
        "nears its stop (franka_sim_gym.training.governor)",
    )
    parser.add_argument(
        "--goal-hold",
        type=float,
        default=None,
        metavar="RADIUS",
        help="(Cartesian velocity) hold the hand still while the object is within RADIUS "
        "metres of its goal (franka_sim_gym.training.goal_hold)",
    )
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument(
        "--curve",
        type=int,
        default=0,
        metavar="EVERY",
        help="also evaluate every EVERY fitting steps and write curve.csv",
    )
    parser.add_argument(
        "--dagger",
        type=int,
        default=0,
        metavar="ROUNDS",
        help="after the fit, this many DAgger rounds: the policy acts, the solver labels",
    )
    parser.add_argument(
        "--dagger-episodes", type=int, default=10, metavar="N", help="episodes per round"
    )
    parser.add_argument(
        "--dagger-id",
        metavar="DATASET_ID",
        help="the rounds' datasets: this id's name with -r<round> "
        "(default: the demonstrations' name with -dagger-seed<seed>)",
    )
    parser.add_argument("--out", type=Path, default=Path("runs/bc"))
    args = parser.parse_args()
    if args.ensemble < 1:
        parser.error(f"--ensemble {args.ensemble}: an ensemble has at least one member")
    if args.curve < 0 or args.curve > args.steps:
        parser.error(f"--curve {args.curve}: evaluate every 1 to --steps ({args.steps}) steps")
    if args.dagger < 0 or (args.dagger and args.dagger_episodes < 1):
        parser.error(
            f"--dagger {args.dagger} --dagger-episodes {args.dagger_episodes}: rounds >= 0, "
            "episodes >= 1"
        )
    if args.dagger_id and not args.dagger:
        parser.error("--dagger-id names the DAgger rounds' datasets: give --dagger too")
    if args.combine != "mean" and args.ensemble < 2:
        parser.error(f"--combine {args.combine} combines members: give --ensemble 2 or more")
    if args.dagger and args.curve:
        parser.error("--dagger and --curve: give one (dagger.csv is the rounds' curve)")

    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import franka_sim_gym  # noqa: F401  (registers the ids)
    from franka_sim_gym.envs.core import FciBatch  # the envs' one constructor
    from franka_sim_gym.training.ensemble import Ensemble, member_file, member_seed
    from franka_sim_gym.training.evaluation import evaluate
    from franka_sim_gym.training.goal_hold import GoalHold
    from franka_sim_gym.training.governor import ElbowGovernor
    from franka_sim_gym.training.line_frame import LineFrame, line_observations, to_line_frame
    from franka_sim_gym.training.sb3_demos import (
        behaviour_cloning,
        demo_arrays,
        load,
        seed_normalization,
    )
    from franka_sim_gym.training.sb3_zoo import NormalizedPolicy, normalization_file
    from franka_sim_gym.training.task_frame import frame_kwargs, frame_rotation

    torch.set_num_threads(args.threads)
    dataset = load(args.demos)
    spec = dataset.env_spec
    interface = spec.kwargs.get("action_interface")
    for flag, used in (
        ("--combine upward", args.combine == "upward"),
        ("--elbow-governor", args.elbow_governor),
        ("--goal-hold", args.goal_hold is not None),
        ("--features line", args.features == "line"),
    ):
        if used and interface != "cartesian_velocity":
            parser.error(
                f"{flag} acts on a Cartesian velocity's entries: {spec.id} has "
                f"action_interface {interface!r}"
            )
    goal_hold = None
    if args.goal_hold is not None:
        # the velocity entries the hold zeroes: the env's cartesian_dof (its own default
        # where the dataset's spec leaves it out)
        default = inspect.signature(FciBatch).parameters["cartesian_dof"].default
        dims = int(spec.kwargs.get("cartesian_dof", default))
        goal_hold = {"radius": args.goal_hold, "velocity_dims": dims}
        try:  # its arguments judged once, by GoalHold itself, before minutes of fitting
            GoalHold(None, **goal_hold)
        except ValueError as error:
            parser.error(f"--goal-hold {args.goal_hold}: {error}")
    # DAgger's labeller, its rounds' datasets and their episode seeds, all checked now
    # (before minutes of fitting): the task's solver, ids that do not exist yet, seeds
    # short of the evaluation's
    round_ids, next_seed = [], 0
    if args.dagger:
        from minari.dataset.minari_dataset import parse_dataset_id
        from scripted import SOLVERS, ScriptedPolicy  # examples/scripted.py, a sibling

        from franka_sim_gym.envs.tasks import TASKS
        from franka_sim_gym.training.datasets import check_new_id, episode_seed

        task = TASKS.get(spec.kwargs.get("task"))
        if task is None or task.id_name not in SOLVERS:
            parser.error(
                f"--dagger: no scripted solver labels {spec.id} (tasks: {sorted(SOLVERS)})"
            )
        naive = "--naive" in str(dataset.storage.metadata.get("algorithm_name") or "")
        seeds = [episode_seed(dataset, k) for k in range(dataset.total_episodes)]
        next_seed = max(seeds) + 1
        if next_seed + args.dagger * args.dagger_episodes > EVALUATION_SEED:
            parser.error(
                f"--dagger: the rounds' episode seeds ({next_seed} on) would reach the "
                f"evaluation's ({EVALUATION_SEED} on)"
            )
        try:
            namespace, name, version = parse_dataset_id(args.dagger_id or args.demos)
            if not args.dagger_id:
                name = f"{name}-dagger-seed{args.seed}"
            prefix = f"{namespace}/{name}" if namespace else name
            round_ids = [f"{prefix}-r{r}-v{version}" for r in range(1, args.dagger + 1)]
            for round_id in round_ids:
                check_new_id(round_id)
        except ValueError as error:
            parser.error(f"--dagger: {error} (or name the rounds with --dagger-id)")
    venv = DummyVecEnv([lambda: gym.make(spec)])
    net = [int(x) for x in args.net.split(",")]
    policy_kwargs: dict = dict(net_arch=net)
    normalize = prepare = None
    features = args.features
    if features == "auto":
        features = "raw" if frame_rotation(venv.observation_space, spec.kwargs) is None else "task"
    if features in ("task", "line"):
        observations = None
        if features == "line":  # the fitting's observations and actions turned
            prepare, observations = to_line_frame, line_observations
        try:
            # (line: joint 4's angle too, the base's one trace: training/line_frame.py)
            kwargs = frame_kwargs(
                dataset, spec.kwargs, venv.observation_space, observations, features == "line"
            )
            policy_kwargs.update(kwargs)
            if prepare is not None:  # labels the actor can reach there, before any fit
                prepare(*demo_arrays(dataset))
        except ValueError as error:
            parser.error(f"--features {features}: {error}")
    else:  # the base-frame observation behind VecNormalize (task: normalised in the network)
        venv = VecNormalize(venv, norm_obs=True, norm_reward=False, gamma=0.95)
        seed_normalization(venv, dataset)
        venv.training = False
        normalize = venv.normalize_obs
    # the curve's points: the fitting steps, each member's actor there, the time to there
    points = [args.steps]
    if args.curve:
        points = sorted({*range(args.curve, args.steps + 1, args.curve), args.steps})
    registered = gym.spec(spec.id).kwargs
    env_kwargs = {k: v for k, v in spec.kwargs.items() if k not in registered or registered[k] != v}

    def fit(demos: list) -> tuple[list, list, dict, dict]:
        """The members fitted from their seeds on ``demos``: the models, the last
        member's losses, each point's wall time (all members) and actors there."""
        actors: dict[int, list] = {step: [] for step in points}
        fitted = dict.fromkeys(points, 0.0)
        models, losses = [], []
        for k in range(args.ensemble):
            seed = member_seed(args.seed, k)
            model = SAC(
                "MultiInputPolicy", venv, buffer_size=1, seed=seed, policy_kwargs=policy_kwargs
            )
            start = time.perf_counter()

            def keep(step: int, model=model, start=start) -> None:
                if step in fitted:
                    fitted[step] += time.perf_counter() - start
                    if args.curve:
                        actors[step].append(copy.deepcopy(model.policy.actor.state_dict()))

            losses = behaviour_cloning(
                model.policy,
                demos,
                args.steps,
                args.batch_size,
                args.lr,
                seed=seed,
                log_every=max(1, args.steps // 5),
                normalize=normalize,
                on_step=keep,
                prepare=prepare,
            )
            models.append(model)
        return models, losses, fitted, actors

    def acting(models: list):
        policy = models[0] if len(models) == 1 else Ensemble(models, args.combine)
        policy = policy if normalize is None else NormalizedPolicy(policy, venv)
        policy = LineFrame(policy) if features == "line" else policy
        policy = ElbowGovernor(policy) if args.elbow_governor else policy
        return policy if goal_hold is None else GoalHold(policy, **goal_hold)

    def evaluated(policy) -> dict:
        return evaluate(policy, spec.id, env_kwargs, args.eval_episodes, seed=EVALUATION_SEED)

    demos = [dataset]
    models, losses, fitted, actors = fit(demos)
    wall = fitted[args.steps]
    policy = acting(models)
    curve = []
    for step in points:
        if args.curve:  # (at the last point these are the final actors)
            for model, actor in zip(models, actors[step], strict=True):
                model.policy.actor.load_state_dict(actor)
        result = evaluated(policy)
        curve.append({"steps": step, "wall_s": round(fitted[step], 1), **rates(result)})
        if args.curve:
            print(
                f"bc curve: steps={step} success_rate={result['success_rate']:.3f} "
                f"reflex_rate={result['reflex_rate']:.3f}",
                flush=True,
            )
    rounds = []
    if args.dagger:
        from franka_sim_gym.training.datasets import record

        solver = ScriptedPolicy(spec.id, naive, env_kwargs)

        def round_row(r: int) -> dict:
            """Round r's row of dagger.csv, from the fits and evaluation so far."""
            labelled = sum(d.total_episodes for d in demos)
            row = {"round": r, "labelled_episodes": labelled, "wall_s": round(wall, 1)}
            return row | rates(result)

        rounds.append(round_row(0))
        for r in range(1, args.dagger + 1):
            learner = policy

            def act(obs: dict, learner=learner):
                return learner.predict(obs, deterministic=True)[0]

            demos.append(
                record(
                    round_ids[r - 1],
                    spec.id,
                    solver,
                    args.dagger_episodes,
                    seed=next_seed,
                    env_kwargs=env_kwargs,
                    num_envs=args.dagger_episodes,
                    algorithm_name=f"examples/train_bc.py --dagger (round {r})",
                    description=f"round {r} of DAgger on {args.demos}: the policy of round "
                    f"{r - 1} acts, the scripted solver of {spec.id} labels",
                    executor=act,
                )
            )
            next_seed += args.dagger_episodes
            models, losses, fitted, _ = fit(demos)
            wall += fitted[args.steps]
            policy = acting(models)
            result = evaluated(policy)
            rounds.append(round_row(r))
            print(
                f"dagger round {r}: {rounds[-1]['labelled_episodes']} labelled episodes, "
                f"success_rate={result['success_rate']:.3f} "
                f"reflex_rate={result['reflex_rate']:.3f}",
                flush=True,
            )
    args.out.mkdir(parents=True, exist_ok=True)
    for k, model in enumerate(models):
        model.save(args.out / member_file(k))
    if normalize is not None:
        stats = normalization_file(args.out / "model.zip")
        stats.parent.mkdir(exist_ok=True)
        venv.save(str(stats))
    config = {"algo": "sac", "env_id": spec.id, "env_kwargs": env_kwargs}
    if len(models) > 1:
        config["members"] = [member_file(k) for k in range(len(models))]
        config["combine"] = args.combine
    if features == "line":
        config["frame"] = "line"
    if args.elbow_governor:
        config["governor"] = "elbow"
    if goal_hold is not None:
        config["goal_hold"] = goal_hold
    (args.out / "train_config.json").write_text(json.dumps(config, indent=2))
    for table, rows in (("curve.csv", curve if args.curve else []), ("dagger.csv", rounds)):
        if rows:
            with open(args.out / table, "w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=list(rows[0]))
                writer.writeheader()
                writer.writerows(rows)
    print(
        f"{spec.id} {env_kwargs}: {dataset.total_episodes} demonstrations"
        + (f" and {len(demos) - 1} DAgger rounds" if len(demos) > 1 else "")
        + f", {sum(d.total_steps for d in demos)} steps; final loss {losses[-1]:.5f}"
        + (f" (the last of {len(models)} members)" if len(models) > 1 else "")
    )
    print(f"reflexes by error: {result['reflexes_by_error'] or 'none'}")
    print(
        f"bc: success_rate={result['success_rate']:.3f} "
        f"reflex_rate={result['reflex_rate']:.3f} wall_s={wall:.1f}"
    )


def rates(result: dict) -> dict:
    """The figures of an evaluation a curve's row holds."""
    return {
        "success_rate": result["success_rate"],
        "reflex_rate": result["reflex_rate"],
        "reflexes_by_error": json.dumps(result["reflexes_by_error"]),
    }


if __name__ == "__main__":
    main()
