"""Behaviour cloning from a Minari dataset: what the demonstrations alone give.

    python examples/train_bc.py --demos franka/push-v0 --out runs/push_bc

The actor of an SB3 SAC policy (the same networks as examples/train_sb3.py --demos)
fitted to the dataset's actions (mean squared error of its deterministic action,
franka_sim_gym.training.sb3_demos.behaviour_cloning; a noise-injected dataset's
demonstrator actions), on the task-frame features of the observation
(``--features task``: franka_sim_gym.training.task_frame, normalised with the dataset's
statistics) or on the whole base-frame observation behind SB3's VecNormalize with the
dataset's statistics (``--features raw``); the default, ``auto``, is ``task`` for the
tasks with an object under a Cartesian interface and ``raw`` for the rest. Then
evaluated as train_sb3.py evaluates (100 episodes side by side, seeds 10,000 on). The
env id and its arguments are the dataset's (``recover_environment``'s spec). Writes
model.zip (with ``raw``: the normalisation, model/vecnormalize.pkl, where
examples/evaluate.py finds it) and train_config.json to --out; last line
``bc: success_rate=<x> reflex_rate=<y> wall_s=<z>``.

``--ensemble K`` fits K actors, member k from seed ``seed + 10,000 k`` (member 0 is the
single actor of ``--seed``), and evaluates the mean of their actions
(franka_sim_gym.training.ensemble); the members are saved as model.zip and
model_member<k>.zip, listed in train_config.json, and load back as one policy.

``--curve EVERY`` also evaluates the policy after every EVERY fitting steps (each member
at that step; the same 100 episodes) and writes the learning curve to curve.csv in
--out: fitting steps, the fitting's wall time to that step (all members), the success
and reflex rates and the reflexes by error name (examples/plot_curves.py draws it). The
last row is the final policy; with or without the curve it is the same, bit for bit
(its rates; the wall time, each member's from its construction to its last step, also
counts the curve's copies of the actors).
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import time
from pathlib import Path


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
        choices=("auto", "task", "raw"),
        default="auto",
        help="task: the task-frame features (object tasks, Cartesian interfaces); raw: the "
        "base-frame observation; auto: task where it applies",
    )
    parser.add_argument(
        "--ensemble", type=int, default=1, metavar="K", help="fit K actors, act on their mean"
    )
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument(
        "--curve",
        type=int,
        default=0,
        metavar="EVERY",
        help="also evaluate every EVERY fitting steps and write curve.csv",
    )
    parser.add_argument("--out", type=Path, default=Path("runs/bc"))
    args = parser.parse_args()
    if args.ensemble < 1:
        parser.error(f"--ensemble {args.ensemble}: an ensemble has at least one member")
    if args.curve < 0 or args.curve > args.steps:
        parser.error(f"--curve {args.curve}: evaluate every 1 to --steps ({args.steps}) steps")

    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import franka_sim_gym  # noqa: F401  (registers the ids)
    from franka_sim_gym.training.ensemble import Ensemble, member_file, member_seed
    from franka_sim_gym.training.evaluation import evaluate
    from franka_sim_gym.training.sb3_demos import behaviour_cloning, load, seed_normalization
    from franka_sim_gym.training.sb3_zoo import NormalizedPolicy, normalization_file
    from franka_sim_gym.training.task_frame import frame_kwargs, frame_rotation

    torch.set_num_threads(args.threads)
    dataset = load(args.demos)
    spec = dataset.env_spec
    venv = DummyVecEnv([lambda: gym.make(spec)])
    net = [int(x) for x in args.net.split(",")]
    policy_kwargs: dict = dict(net_arch=net)
    normalize = None
    features = args.features
    if features == "auto":
        features = "raw" if frame_rotation(venv.observation_space, spec.kwargs) is None else "task"
    if features == "task":
        try:
            policy_kwargs.update(frame_kwargs(dataset, spec.kwargs, venv.observation_space))
        except ValueError as error:
            parser.error(str(error))
    else:  # the base-frame observation behind VecNormalize (task: normalised in the network)
        venv = VecNormalize(venv, norm_obs=True, norm_reward=False, gamma=0.95)
        seed_normalization(venv, dataset)
        venv.training = False
        normalize = venv.normalize_obs
    # the curve's points: the fitting steps, each member's actor there, the time to there
    points = [args.steps]
    if args.curve:
        points = sorted({*range(args.curve, args.steps + 1, args.curve), args.steps})
    actors: dict[int, list] = {step: [] for step in points}
    fitted = dict.fromkeys(points, 0.0)
    models, losses = [], []
    for k in range(args.ensemble):
        seed = member_seed(args.seed, k)
        model = SAC("MultiInputPolicy", venv, buffer_size=1, seed=seed, policy_kwargs=policy_kwargs)
        start = time.perf_counter()

        def keep(step: int, model=model, start=start) -> None:
            if step in fitted:
                fitted[step] += time.perf_counter() - start
                if args.curve:
                    actors[step].append(copy.deepcopy(model.policy.actor.state_dict()))

        losses = behaviour_cloning(
            model.policy,
            dataset,
            args.steps,
            args.batch_size,
            args.lr,
            seed=seed,
            log_every=max(1, args.steps // 5),
            normalize=normalize,
            on_step=keep,
        )
        models.append(model)
    wall = fitted[args.steps]
    registered = gym.spec(spec.id).kwargs
    env_kwargs = {k: v for k, v in spec.kwargs.items() if k not in registered or registered[k] != v}
    policy = models[0] if len(models) == 1 else Ensemble(models)
    policy = policy if normalize is None else NormalizedPolicy(policy, venv)
    curve = []
    for step in points:
        if args.curve:  # (at the last point these are the final actors)
            for model, actor in zip(models, actors[step], strict=True):
                model.policy.actor.load_state_dict(actor)
        result = evaluate(policy, spec.id, env_kwargs, args.eval_episodes, seed=10_000)
        curve.append(
            {
                "steps": step,
                "wall_s": round(fitted[step], 1),
                "success_rate": result["success_rate"],
                "reflex_rate": result["reflex_rate"],
                "reflexes_by_error": json.dumps(result["reflexes_by_error"]),
            }
        )
        if args.curve:
            print(
                f"bc curve: steps={step} success_rate={result['success_rate']:.3f} "
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
    (args.out / "train_config.json").write_text(json.dumps(config, indent=2))
    if args.curve:
        with open(args.out / "curve.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(curve[0]))
            writer.writeheader()
            writer.writerows(curve)
    print(
        f"{spec.id} {env_kwargs}: {dataset.total_episodes} demonstrations, "
        f"{dataset.total_steps} steps; final loss {losses[-1]:.5f}"
        + (f" (the last of {len(models)} members)" if len(models) > 1 else "")
    )
    print(f"reflexes by error: {result['reflexes_by_error'] or 'none'}")
    print(
        f"bc: success_rate={result['success_rate']:.3f} "
        f"reflex_rate={result['reflex_rate']:.3f} wall_s={wall:.1f}"
    )


if __name__ == "__main__":
    main()
