"""Train a reach policy on FrankaFCI with stable-baselines3, evaluating it as it goes.

    python examples/train_sb3.py --out runs/reach            # the default reach (below)
    python examples/train_sb3.py --env-id FrankaFCI-v0 --env-kwargs '{"policy_hz": 25}'
    python examples/train_sb3.py --algo ppo --num-envs 1 --steps 50000 --out runs/ppo

The default: SAC + HER on FrankaFCICartesianVelocity-v0 (a 3-D twist, orientation held,
10 Hz policy, 2 s episodes) in 16 batched arms (the native batched env,
franka_sim_gym.training.sb3_vec_env), behind SB3's observation normalisation, SB3's SAC,
one gradient step per sample on one torch thread, 8,000 samples, HER through the buffer
that keeps the reflex charge of relabelled steps (franka_sim_gym.training.sb3_her), SAC's
entropy weight tuned from 0.02.
Every cycle runs the full FCI at 1 kHz: the libfranka client's filters, every
motion-limit check including the IK joint side, the safety controller. Reflexes
terminate episodes, as on the robot. docs/training.md tells the settings and figures.

Observations are normalised by SB3's ``VecNormalize`` (rewards left as they are; the
statistics saved beside the model, where examples/evaluate.py and
examples/deploy_pylibfranka.py find them); ``--no-normalize`` trains on the raw ones.
Without it the policy learns to ignore the goal (docs/training.md, "Why normalise").
``--eval-every N`` evaluates every N samples (instead of ``--evals`` times), and
``--time-limit S`` stops at the first evaluation after S seconds, saving what it has.

``--demos DATASET_ID`` learns from demonstrations (a Minari dataset recorded on the same
id and env arguments, e.g. by examples/scripted.py --record): SAC + HER whose batches
are ``--demo-fraction`` demonstrations (franka_sim_gym.training.sb3_demos), learning from
the first step, with ``--bc-weight W`` a behaviour-cloning term in the actor's loss and
``--bc-steps N`` the actor fitted to the demonstrations first; ``--gamma`` and ``--tau``
set SAC's. ``--imitation RUN`` (SAC on raw observations: ``--features task`` or
``--no-normalize``) keeps a fitted policy (a train_bc.py ``--out`` folder, acting in
the same env) beside SAC's actor: the critics choose between their actions at every
step and bootstrap from the better (IBRL: franka_sim_gym.training.ibrl); the run's
train_config.json names it, and evaluate.py loads the two together.
docs/demonstrations.md tells the recipe and its figures.

Writes to --out: model.zip, train_config.json (algo, env id and arguments, read by
examples/evaluate.py and examples/deploy_pylibfranka.py), progress.csv (SB3's logger;
TensorBoard events too with ``--tensorboard``: ``tensorboard --logdir DIR``), eval.csv
(rewritten after every evaluation: samples, success and reflex rates, the reflexes by
error, wall seconds) and success_reflex.png (when matplotlib is installed). A progress
bar on stderr (``--no-progress``). Ends with one line
``eval: success_rate=<x> reflex_rate=<y> wall_s=<z>``.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.training.evaluation import EVALUATION_SEED, evaluate
from franka_sim_gym.training.sb3_zoo import NormalizedPolicy, normalization_file

#: The default reach: a 3-D twist (orientation held) at 10 Hz, 2 s episodes.
DEFAULT_ENV_KWARGS = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 20}


def make_model(
    algo: str,
    env,
    seed: int,
    log_dir: Path,
    gradient_steps: int = 1,
    learning_starts: int = 300,
    net: tuple[int, ...] = (64, 64),
    batch_size: int = 256,
    sde: bool = False,
    tensorboard: bool = False,
    buffer_size: int = 1_000_000,
    ent_coef: str = "auto_0.02",
    threads: int = 1,
    demos: dict | None = None,
    features: dict | None = None,
    imitation=None,
):
    """The SB3 model of the default run (``algo`` "sac"), or TD3 / PPO on the same env;
    with ``imitation`` (a policy with SB3's ``predict``), SAC with IBRL's acting and
    bootstrapping (franka_sim_gym.training.ibrl)."""
    import torch
    from stable_baselines3 import PPO, SAC, TD3
    from stable_baselines3.common.logger import configure

    from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer

    # One torch thread by default: at these sizes a second one takes a gradient step
    # little faster on an idle 2-core machine, and several times slower while another
    # process wants a core (its threads wait for each other at every parallel region);
    # the thread count changes no bit of the run (benchmarks/sac_step.py,
    # docs/training.md).
    torch.set_num_threads(threads)
    common = dict(policy="MultiInputPolicy", env=env, seed=seed, verbose=0)
    # Off-policy learners relabel goals with HER (the env's vectorised compute_reward),
    # keeping each step's reflex charge so that a relabelled reflex is no success.
    off_policy = dict(
        replay_buffer_class=ReflexChargedHerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
        # HER samples whole episodes: learning waits for every arm's first one to end.
        learning_starts=learning_starts,
        # HER scans every slot for finished episodes at each gradient step: a buffer
        # that just holds the run samples the same transitions as SB3's million-slot
        # default, without the scan of the empty slots.
        buffer_size=buffer_size,
        batch_size=batch_size,
        gamma=0.95,
        learning_rate=1e-3,
        tau=0.05,  # rl-zoo's PandaReach settings: fast target networks
        # foreach Adam: one kernel per parameter group, not per tensor (~10 % of a step)
        policy_kwargs=dict(
            net_arch=list(net), optimizer_kwargs=dict(foreach=True), **(features or {})
        ),
        gradient_steps=gradient_steps,
    )
    if demos:
        # --demos: every batch part demonstrations (franka_sim_gym.training.sb3_demos)
        from franka_sim_gym.training.sb3_demos import DemoMixedHerReplayBuffer

        off_policy["replay_buffer_class"] = DemoMixedHerReplayBuffer
        off_policy["replay_buffer_kwargs"].update(demos)
    if algo == "sac":
        # gSDE: exploration noise that is smooth in time, which a rate-limited robot
        # does not average away between steps.
        # ent_coef "auto_0.02": tuned as SB3's "auto", but from 0.02 instead of 1. With
        # rewards of -1 a step, an entropy weight of 1 outweighs the task: in the default
        # run it took ~5,500 samples to fall to the ~0.015 where it settles, and nothing
        # was learnt before (docs/training.md).
        if imitation is None:
            model = SAC(**common, **off_policy, use_sde=sde, ent_coef=ent_coef)
        else:
            from franka_sim_gym.training.ibrl import ImitationBootstrappedSAC

            model = ImitationBootstrappedSAC(**common, **off_policy, use_sde=sde, ent_coef=ent_coef)
            model.imitation = imitation
    elif algo == "td3":
        model = TD3(**common, **off_policy)
    elif algo == "ppo":
        model = PPO(**common, n_steps=512, batch_size=128, gamma=0.95)
    else:
        raise ValueError(f"unknown --algo {algo!r}: expected sac, td3 or ppo")
    model.set_logger(configure(str(log_dir), log_formats(tensorboard)))
    return model


def log_formats(tensorboard: bool = False) -> list[str]:
    """SB3's logger outputs: progress.csv always; TensorBoard events too with
    ``tensorboard`` (``--tensorboard``; the train extra brings the package). Off by
    default: its writer makes the default run about a fifth slower."""
    if not tensorboard:
        return ["csv"]
    try:
        import tensorboard as _  # noqa: F401
    except ImportError:
        print("tensorboard not installed: CSV logs only")
        return ["csv"]
    return ["csv", "tensorboard"]


def progress_bar(total: int, enabled: bool = True):
    """One tqdm bar over the whole run (the evaluations split it into several
    ``learn`` calls), as an SB3 callback; None when disabled or tqdm is missing."""
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # the train extra brings it
        print("tqdm not installed: no progress bar")
        return None
    from stable_baselines3.common.callbacks import BaseCallback

    class _Progress(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.bar = tqdm(total=total, unit="sample", desc="training", smoothing=0.1)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

    return _Progress()


def write_curve(out: Path, rows: list[dict]) -> None:
    """eval.csv: one row per evaluation (the reflexes by error as JSON)."""
    with open(out / "eval.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def plot(out: Path, rows: list[dict], title: str = "FrankaFCI reach") -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # the train extra brings it
        print("matplotlib not installed: no plot")
        return
    steps = [r["steps"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(steps, [r["success_rate"] for r in rows], marker="o", label="success rate")
    ax.plot(steps, [r["reflex_rate"] for r in rows], marker="x", label="reflex rate")
    ax.set_xlabel("environment steps")
    ax.set_ylim(-0.05, 1.05)
    ax.legend()
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(out / "success_reflex.png", dpi=100)


def load_imitation(parser: argparse.ArgumentParser, args: argparse.Namespace):
    """--imitation's policy and its settings (evaluate.py's load_model), or the parser's
    error naming why it cannot serve this run (before any step)."""
    if args.algo != "sac":
        parser.error(
            f"--imitation chooses between SAC's actor and a policy: not --algo {args.algo}"
        )
    if args.normalize:  # the critics and the imitation policy see one observation
        parser.error(
            "--imitation hands the imitation policy the observations SAC sees: give "
            "--features task or --no-normalize (not SB3's VecNormalize)"
        )
    if args.sde:  # its update resamples no gSDE noise (training/ibrl.py)
        parser.error("--imitation trains SAC without --sde")
    from evaluate import load_model, model_file, train_config  # examples/evaluate.py

    try:
        run = model_file(args.imitation)
    except FileNotFoundError as error:
        parser.error(f"--imitation {args.imitation}: {error}")
    if not train_config(run):
        parser.error(
            f"--imitation {args.imitation}: no train_config.json beside {run.name} (a "
            "train_bc.py or train_sb3.py run names its env there)"
        )
    return load_model(run)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algo", default="sac", choices=("sac", "td3", "ppo"))
    parser.add_argument("--steps", type=int, default=8000, help="environment steps")
    parser.add_argument("--evals", type=int, default=4, help="evaluations during training")
    parser.add_argument(
        "--eval-every", type=int, default=None, help="samples between evaluations (over --evals)"
    )
    parser.add_argument(
        "--time-limit",
        type=float,
        default=None,
        help="seconds: stop at the first evaluation past it and save the model",
    )
    parser.add_argument(
        "--normalize",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="observation normalisation (SB3's VecNormalize, rewards left as they are; default on)",
    )
    parser.add_argument("--eval-episodes", type=int, default=32)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--num-envs",
        type=int,
        default=16,
        help="arms trained on at once: > 1 uses the native batched env (one MuJoCo world)",
    )
    parser.add_argument("--env-id", default="FrankaFCICartesianVelocity-v0")
    parser.add_argument(
        "--gradient-steps",
        type=int,
        default=None,
        help="per vector step (default: --num-envs, one per sample)",
    )
    parser.add_argument("--net", default="128,128", help="hidden layer sizes")
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--sde", action="store_true", help="SAC: state-dependent exploration")
    parser.add_argument(
        "--ent-coef",
        default="auto_0.02",
        help="SAC's entropy coefficient: a number, or auto_<initial value> to tune it",
    )
    parser.add_argument(
        "--threads", type=int, default=1, help="torch threads for the gradient steps"
    )
    parser.add_argument(
        "--env-kwargs",
        default="{}",
        help=f"JSON, merged over the defaults {json.dumps(DEFAULT_ENV_KWARGS)}",
    )
    parser.add_argument("--out", type=Path, default=Path("runs/reach"))
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--tensorboard", action="store_true", help="TensorBoard events next to progress.csv"
    )
    parser.add_argument(
        "--features",
        choices=("raw", "task"),
        default="raw",
        help="task (SAC / TD3 with --demos): the policy sees the task-frame features of an "
        "object task (franka_sim_gym.training.task_frame; normalised inside with the "
        "dataset's statistics, so no --normalize)",
    )
    demo = parser.add_argument_group("learning from demonstrations (docs/demonstrations.md)")
    demo.add_argument("--demos", metavar="DATASET_ID", help="a Minari dataset of the env")
    demo.add_argument(
        "--demo-fraction", type=float, default=0.5, help="demonstrations' share of a batch"
    )
    demo.add_argument("--bc-weight", type=float, default=0.0, help="behaviour-cloning term")
    demo.add_argument("--bc-steps", type=int, default=0, help="actor fitted to them first")
    demo.add_argument(
        "--bc-std",
        type=float,
        default=None,
        help="with --bc-steps: the exploration std (before tanh) the actor is fitted to",
    )
    demo.add_argument(
        "--actor-warmup",
        type=int,
        default=0,
        help="actor steps that take the behaviour-cloning gradient only (SAC's own after)",
    )
    demo.add_argument("--gamma", type=float, default=None, help="SAC's discount (0.95)")
    demo.add_argument("--tau", type=float, default=None, help="SAC's target update (0.05)")
    demo.add_argument("--learning-starts", type=int, default=None, help="samples before learning")
    demo.add_argument(
        "--imitation",
        type=Path,
        metavar="RUN",
        help="SAC with a fitted policy beside its actor (IBRL): a train_bc.py --out folder",
    )
    args = parser.parse_args()
    if args.features == "task":
        if not args.demos or args.algo == "ppo":
            parser.error(
                "--features task is for SAC / TD3 with --demos (its features are normalised "
                "with the dataset's statistics)"
            )
        args.normalize = False  # the task frame normalises its features itself
    if args.bc_std is not None and not args.bc_steps:
        parser.error("--bc-std sets the exploration the actor is cloned to: give --bc-steps")
    if args.actor_warmup and not args.demos:
        parser.error("--actor-warmup holds SAC's actor to the demonstrations: give --demos")
    if args.algo != "sac" and (args.bc_std is not None or args.actor_warmup):
        # TD3's actor has no exploration distribution to fit, nor a deterministic switch
        parser.error(f"--bc-std and --actor-warmup act on SAC's actor, not --algo {args.algo}")
    imitation, imitated = load_imitation(parser, args) if args.imitation else (None, None)
    args.out.mkdir(parents=True, exist_ok=True)
    kwargs = {**DEFAULT_ENV_KWARGS, **json.loads(args.env_kwargs)}
    merged = {**gym.spec(args.env_id).kwargs, **kwargs}  # the env's whole arguments
    if args.num_envs > 1:
        from franka_sim_gym.training.sb3_vec_env import FrankaFCISB3VecEnv

        env = FrankaFCISB3VecEnv(args.num_envs, **merged)
    else:
        env = gym.make(args.env_id, **kwargs)
    if args.normalize:
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        if args.num_envs <= 1:
            single = env
            env = DummyVecEnv([lambda: single])
        # Every key, goals too, as rl-zoo3's FetchReach and the shipped sac.yml: HER
        # stores the raw observations and normalises the relabelled ones at sampling.
        env = VecNormalize(env, norm_obs=True, norm_reward=False, gamma=0.95)
    config = {"algo": args.algo, "env_id": args.env_id, "env_kwargs": kwargs}
    if imitation is not None:
        theirs = gym.make(imitated["env_id"], **imitated["env_kwargs"])
        spaces = (theirs.observation_space, theirs.action_space)
        theirs.close()
        if imitated["env_id"] != args.env_id or spaces != (
            env.observation_space,
            env.action_space,
        ):
            parser.error(
                f"--imitation {args.imitation} acts in {imitated['env_id']} "
                f"{imitated['env_kwargs']}, whose spaces are not this run's ({args.env_id})"
            )
        config["imitation"] = str(args.imitation.resolve())
    (args.out / "train_config.json").write_text(json.dumps(config, indent=2))
    episode_steps = int(
        kwargs.get("max_episode_steps", gym.spec(args.env_id).kwargs.get("max_episode_steps", 50))
    )
    learning_starts = max(300, args.num_envs * (episode_steps + 1))
    if args.learning_starts is not None:
        learning_starts = args.learning_starts
    demos = None
    if args.demos:
        from franka_sim_gym.training.sb3_demos import load, seed_normalization

        demos = {"demos": load(args.demos), "demo_fraction": args.demo_fraction}
        if args.normalize:  # statistics from the demonstrations before the first step
            seed_normalization(env, demos["demos"])
    features = None
    if args.features == "task":
        from franka_sim_gym.training.task_frame import frame_kwargs

        try:
            features = frame_kwargs(demos["demos"], merged, env.observation_space)
        except ValueError as error:
            parser.error(str(error))
    chunk = args.eval_every or max(1, args.steps // args.evals)
    # SB3 collects whole vector steps: each learn call's samples round up to the arms.
    chunks = [min(chunk, args.steps - k) for k in range(0, args.steps, chunk)]
    arms = max(1, args.num_envs)
    collected = sum(-(-n // arms) * arms for n in chunks)
    model = make_model(
        args.algo,
        env,
        args.seed,
        args.out,
        args.num_envs if args.gradient_steps is None else args.gradient_steps,
        learning_starts,
        tuple(int(x) for x in args.net.split(",")),
        args.batch_size,
        args.sde,
        args.tensorboard,
        buffer_size=min(1_000_000, collected + arms),  # the whole run, one spare step
        ent_coef=args.ent_coef,
        threads=args.threads,
        demos=demos,
        features=features,
        imitation=imitation,
    )
    if args.gamma is not None:
        model.gamma = args.gamma
    if args.tau is not None:
        model.tau = args.tau
    start = time.perf_counter()
    if args.demos:  # (in the run's time)
        from franka_sim_gym.training.sb3_demos import add_behaviour_cloning, behaviour_cloning

        normalize = env.normalize_obs if args.normalize else None
        if args.bc_steps:
            behaviour_cloning(
                model.policy,
                demos["demos"],
                args.bc_steps,
                normalize=normalize,
                exploration_std=args.bc_std,
            )
        if args.bc_weight or args.actor_warmup:
            add_behaviour_cloning(
                model, demos["demos"], args.bc_weight, normalize, args.seed, args.actor_warmup
            )
    rows = []
    bar = progress_bar(collected, enabled=not args.no_progress)
    done = 0
    while done < args.steps:
        n = min(chunk, args.steps - done)
        model.learn(total_timesteps=n, reset_num_timesteps=False, callback=bar)
        done += n
        # the model behind the statistics as they stand (frozen for the evaluation only)
        policy = NormalizedPolicy(model, env, freeze=False) if args.normalize else model
        result = evaluate(policy, args.env_id, kwargs, args.eval_episodes, seed=EVALUATION_SEED)
        rows.append(
            {
                "steps": done,
                **{k: v for k, v in result.items() if k != "reflexes_by_error"},
                "reflexes_by_error": json.dumps(result["reflexes_by_error"], sort_keys=True),
                "wall_s": round(time.perf_counter() - start, 1),
            }
        )
        write_curve(args.out, rows)
        print(
            f"steps {done}: success {result['success_rate']:.2f} "
            f"reflexes {result['reflex_rate']:.2f} {result['reflexes_by_error']}",
            flush=True,
        )
        if args.time_limit is not None and time.perf_counter() - start > args.time_limit:
            print(f"time limit of {args.time_limit:.0f} s reached at {done} samples")
            break
    wall = time.perf_counter() - start
    if bar is not None:
        bar.bar.close()
    if args.demos:  # saved with the plain buffer: the model loads without the dataset
        from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer

        model.replay_buffer_class = ReflexChargedHerReplayBuffer
        model.replay_buffer_kwargs = {
            k: v for k, v in model.replay_buffer_kwargs.items() if k not in demos
        }
    model.save(args.out / "model.zip")
    if args.normalize:
        # where examples/evaluate.py (franka_sim_gym.training.sb3_zoo) looks for it
        stats = normalization_file(args.out / "model.zip")
        stats.parent.mkdir(exist_ok=True)
        env.save(str(stats))
    plot(args.out, rows, args.env_id)
    final = rows[-1]
    print(
        f"eval: success_rate={final['success_rate']:.3f} "
        f"reflex_rate={final['reflex_rate']:.3f} wall_s={wall:.1f}"
    )


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
