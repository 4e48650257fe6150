"""Train PPO on a FrankaFCI id with Ray RLlib (new API stack), the batched env in every runner.

    pip install 'franka-sim-gym[rllib]'
    python examples/train_rllib.py            # the reach: 2 runners x 32 arms, 320,000 steps
    python examples/train_rllib.py --evaluate runs/rllib/checkpoint --episodes 100
                          # (env id and arguments from train_config.json beside it)
    python examples/train_rllib.py --address auto ...      # on a running Ray cluster

What a user would otherwise have to find out:

* the env is named ``"franka_sim_gym:<id>"``: Gymnasium imports ``franka_sim_gym``
  (which registers the ids) in every env-runner process before it looks the id up; a
  bare id is unknown to runners that never imported the package;
* the Dict observation goes through RLlib's ``FlattenObservations`` connector (RLlib has
  no default encoder for a Dict space);
* ``gym_env_vectorize_mode="vector_entry_point"``: each runner steps its
  ``--envs-per-runner`` arms as one native batched env (one MuJoCo world, one
  controller call per cycle), not as that many single envs.

Writes RLlib's checkpoint to ``--out``/checkpoint and evaluates it with the package's
own evaluation (franka_sim_gym.training.evaluation: success rate, reflex rate; the
policy's deterministic action). Prints, last, one line
``rllib: env_id=... runners=R envs_per_runner=N env_steps_per_s=X episode_return_mean=Y``
(env steps per second of training, sampling and learning, over the iterations after
the first, whose time includes the runners' start; benchmarks/rllib_scaling.py times
the sampling alone).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

#: The default env: the Cartesian twist reach of examples/train_sb3.py's default run.
DEFAULT_ENV_ID = "FrankaFCICartesianVelocity-v0"
#: RLlib has no HER: its learners take the env's reward as it is, and the sparse one
#: (-1 until the goal) gives PPO nothing to follow until it happens on a goal by chance.
DEFAULT_ENV_KWARGS = {
    "cartesian_dof": 3,
    "policy_hz": 10,
    "max_episode_steps": 20,
    "reward_type": "dense",
}


#: ``--algo``: RLlib algorithms the recipe configures
ALGOS = ("ppo", "sac")


def build_config(
    env_id: str,
    env_kwargs: dict,
    runners: int,
    envs_per_runner: int,
    seed: int,
    batch_size: int,
    algo: str = "ppo",
):
    """RLlib's PPO (or SAC) configuration for ``env_id`` with ``runners`` env runners,
    each stepping ``envs_per_runner`` arms of one native batched env.

    PPO: ``batch_size`` env steps per iteration, 10 epochs of minibatches of 1,024,
    gamma 0.95, GAE lambda 0.95, lr 5e-4 (docs/scaling.md, "What the recipe learns").
    SAC: batches of 256 drawn from RLlib's episode replay buffer, one gradient step per
    env step sampled (``training_intensity`` 256), the learning rates of the default SB3
    run (1e-3), tau 0.05, gamma 0.95, the entropy weight from 0.02, learning after 512
    env steps, ``batch_size`` env steps an iteration. RLlib has no HER: both learn from
    the reward the env gives (the default env arguments ask for the dense one).
    Observations are flattened, then normalised by RLlib's ``MeanStdFilter``."""
    from ray.rllib.connectors.env_to_module import FlattenObservations, MeanStdFilter

    if algo == "ppo":
        from ray.rllib.algorithms.ppo import PPOConfig

        config = PPOConfig().training(
            train_batch_size_per_learner=batch_size,
            minibatch_size=min(1024, batch_size),
            num_epochs=10,
            gamma=0.95,
            lambda_=0.95,
            lr=5e-4,
        )
    elif algo == "sac":
        from ray.rllib.algorithms.sac import SACConfig

        config = SACConfig().training(
            train_batch_size_per_learner=256,
            training_intensity=256,  # one gradient step of 256 per env step sampled
            num_steps_sampled_before_learning_starts=512,
            gamma=0.95,
            tau=0.05,
            actor_lr=1e-3,
            critic_lr=1e-3,
            alpha_lr=1e-3,
            initial_alpha=0.02,
        )
        # the new API stack reads the network from rl_module(model_config=...); a
        # training(model=...) is ignored there (RLlib warns and builds [256, 256])
        config = config.rl_module(model_config={"fcnet_hiddens": [128, 128]}).reporting(
            min_time_s_per_iteration=0, min_sample_timesteps_per_iteration=batch_size
        )
    else:
        raise ValueError(f"unknown algo {algo!r}: expected one of {ALGOS}")
    return (
        config.environment(f"franka_sim_gym:{env_id}", env_config=env_kwargs)
        .env_runners(
            num_env_runners=runners,
            num_envs_per_env_runner=envs_per_runner,
            gym_env_vectorize_mode="vector_entry_point",
            # the Dict observation flattened, then normalised by running mean and std
            # (the SB3 recipe's VecNormalize, for the same reason: docs/training.md)
            env_to_module_connector=lambda env, spaces=None, device=None: [
                FlattenObservations(),
                MeanStdFilter(),
            ],
            num_cpus_per_env_runner=1,
            # RLlib's default (60 s) gives up on a runner that samples slowly, as on a
            # busy machine, and the iteration then reports no episodes: wait for it.
            sample_timeout_s=None,
        )
        .debugging(seed=seed)
    )


class RLlibPolicy:
    """An RLlib module's deterministic action, behind SB3's ``predict`` (what
    ``franka_sim_gym.training.evaluation.evaluate`` calls). The Dict observation is
    flattened as ``FlattenObservations`` does (its keys in sorted order, concatenated),
    then normalised by ``observation_filter`` (RLlib's ``MeanStdFilter`` with the
    training's statistics, frozen), as the env runners' connectors did in training."""

    def __init__(self, module, observation_filter=None) -> None:
        self.module = module
        self.observation_filter = observation_filter

    def predict(self, obs: dict, deterministic: bool = True):
        import torch

        flat = np.concatenate([np.asarray(obs[k], np.float32) for k in sorted(obs)], axis=-1)
        if self.observation_filter is not None:
            flat = np.asarray(self.observation_filter(flat, update=False), np.float32)
        with torch.no_grad():
            out = self.module.forward_inference({"obs": torch.from_numpy(flat)})
            dist = self.module.get_inference_action_dist_cls().from_logits(
                out["action_dist_inputs"]
            )
            action = dist.to_deterministic().sample().numpy()
        return np.clip(action, -1.0, 1.0), None


def observation_filter(state: dict):
    """RLlib's ``MeanStdFilter`` (ray.rllib.utils.filter) holding the statistics of an
    env-to-module pipeline's state (``{connector name: its state}``), as the connector's
    own ``set_state`` restores them; None when the pipeline has no ``MeanStdFilter``."""
    import tree  # dm-tree, RLlib's dependency
    from ray.rllib.utils.filter import MeanStdFilter, RunningStat

    for name, connector_state in state.items():
        if name.startswith("MeanStdFilter") and connector_state:
            agent = next(iter(connector_state.values()))  # single-agent: one filter
            result = MeanStdFilter(
                agent["shape"],
                demean=agent["de_mean_to_zero"],
                destd=agent["de_std_to_one"],
                clip=agent["clip_by_value"],
            )
            result.running_stats = tree.unflatten_as(
                agent["shape"], [RunningStat.from_state(s) for s in agent["running_stats"]]
            )
            return result
    return None


def load_policy(checkpoint: Path) -> RLlibPolicy:
    """The trained policy of an RLlib checkpoint (the learner's default module) with the
    observation normalisation its env runners trained behind."""
    from ray.rllib.connectors.env_to_module import EnvToModulePipeline
    from ray.rllib.core import (
        COMPONENT_ENV_RUNNER,
        COMPONENT_ENV_TO_MODULE_CONNECTOR,
        COMPONENT_LEARNER,
        COMPONENT_LEARNER_GROUP,
        COMPONENT_RL_MODULE,
        DEFAULT_MODULE_ID,
    )
    from ray.rllib.core.rl_module.rl_module import RLModule

    path = (
        Path(checkpoint)
        / COMPONENT_LEARNER_GROUP
        / COMPONENT_LEARNER
        / COMPONENT_RL_MODULE
        / DEFAULT_MODULE_ID
    )
    module = RLModule.from_checkpoint(path.resolve())
    connectors = Path(checkpoint) / COMPONENT_ENV_RUNNER / COMPONENT_ENV_TO_MODULE_CONNECTOR
    pipeline = EnvToModulePipeline.from_checkpoint(connectors.resolve())
    return RLlibPolicy(module, observation_filter(pipeline.get_state()))


def start_local_ray(address: str | None = None) -> None:
    """``ray.init``: a local Ray (``address`` None) or a running cluster's.

    A local Ray starts its workers, the env runners among them, at the niceness of this
    process: Ray's default lowers their priority by 15 (``RAY_worker_niceness``), which on
    a machine shared with other work leaves the runners, which do the sampling, only what
    every other process leaves over (docs/scaling.md). ``RAY_worker_niceness`` set in the
    environment wins; a cluster's nodes take it from ``ray start``'s environment.
    """
    import ray

    if address is None:
        os.environ.setdefault("RAY_worker_niceness", "0")
    ray.init(address=address, include_dashboard=False, log_to_driver=False)


def observation_statistics_to_local_runner(algo) -> None:
    """Copy a remote env runner's env-to-module state (the ``MeanStdFilter``'s statistics)
    to the algorithm's local env runner, whose state ``save_to_path`` writes.

    With remote runners, RLlib 2.60 merges their filter statistics and broadcasts them
    to the remote runners only: the local runner, which samples nothing, keeps a filter
    of zero pushes, and a checkpoint saved as it is would evaluate the policy on raw
    observations (measured: every evaluation episode a reflex)."""
    from ray.rllib.core import COMPONENT_ENV_TO_MODULE_CONNECTOR

    if algo.env_runner is None or algo.env_runner_group.num_healthy_remote_workers() == 0:
        return
    states = algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.get_state(components=COMPONENT_ENV_TO_MODULE_CONNECTOR),
        local_env_runner=False,
    )
    algo.env_runner.set_state(states[0])


def train(args, env_kwargs: dict) -> tuple[Path, float, float]:
    """Train; returns (checkpoint, env steps per second of training, last episode return)."""
    import ray

    start_local_ray(args.address)
    config = build_config(
        args.env_id,
        env_kwargs,
        args.runners,
        args.envs_per_runner,
        args.seed,
        args.batch_size,
        args.algo,
    )
    algo = config.build_algo()
    # Each runner's node, by the address the node was started with (ray start
    # --node-ip-address): the machine's own address is the same for every node of a
    # cluster on one machine's loopback addresses (docs/scaling.md).
    node_ids = algo.env_runner_group.foreach_env_runner(
        lambda runner: ray.get_runtime_context().get_node_id(), local_env_runner=False
    )
    addresses = {node["NodeID"]: node["NodeManagerAddress"] for node in ray.nodes()}
    nodes = [addresses.get(node_id, node_id) for node_id in node_ids]
    print(f"env runners on nodes: {', '.join(sorted(nodes))}", flush=True)
    steps = seconds = 0.0
    episode_return = float("nan")
    for iteration in range(args.iterations):
        start = time.perf_counter()
        result = algo.train()
        elapsed = time.perf_counter() - start
        runners = result.get("env_runners", {})
        sampled = float(runners.get("num_env_steps_sampled", 0))
        episode_return = float(runners.get("episode_return_mean", float("nan")))
        if iteration > 0 or args.iterations == 1:
            steps += sampled
            seconds += elapsed
        print(
            f"iteration {iteration + 1}: {sampled:.0f} env steps in {elapsed:.1f} s, "
            f"episode_return_mean {episode_return:.2f}",
            flush=True,
        )
    observation_statistics_to_local_runner(algo)
    checkpoint = Path(algo.save_to_path(str((args.out / "checkpoint").resolve())))
    algo.stop()
    ray.shutdown()
    return checkpoint, steps / seconds if seconds > 0 else float("nan"), episode_return


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algo", default="ppo", choices=ALGOS)
    parser.add_argument("--env-id", default=None, help=f"default: {DEFAULT_ENV_ID}")
    parser.add_argument(
        "--env-kwargs",
        default=None,
        help=f"JSON, merged over the defaults {json.dumps(DEFAULT_ENV_KWARGS)}",
    )
    parser.add_argument("--runners", type=int, default=2, help="RLlib env runners")
    parser.add_argument(
        "--envs-per-runner", type=int, default=32, help="arms of each runner's batched env"
    )
    parser.add_argument("--iterations", type=int, default=20, help="RLlib train() calls")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--batch-size", type=int, default=16000, help="env steps per training iteration"
    )
    parser.add_argument("--out", type=Path, default=Path("runs/rllib"))
    parser.add_argument(
        "--address", default=None, help="a Ray cluster's address (default: a local Ray)"
    )
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes")
    parser.add_argument("--evaluate", type=Path, default=None, help="only evaluate this checkpoint")
    args = parser.parse_args()
    # --evaluate: the env the checkpoint was trained on (train_config.json beside it)
    saved = args.evaluate.parent / "train_config.json" if args.evaluate else None
    trained = json.loads(saved.read_text()) if saved and saved.exists() else {}
    args.env_id = args.env_id or trained.get("env_id", DEFAULT_ENV_ID)
    env_kwargs = {**DEFAULT_ENV_KWARGS, **trained.get("env_kwargs", {})}
    env_kwargs.update(json.loads(args.env_kwargs or "{}"))
    from franka_sim_gym.training.evaluation import EVALUATION_SEED, evaluate

    if args.evaluate is None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "train_config.json").write_text(
            json.dumps(
                {"algo": f"rllib_{args.algo}", "env_id": args.env_id, "env_kwargs": env_kwargs}
            )
        )
        checkpoint, rate, episode_return = train(args, env_kwargs)
    else:
        checkpoint, rate, episode_return = args.evaluate, float("nan"), float("nan")
    result = evaluate(
        load_policy(checkpoint), args.env_id, env_kwargs, args.episodes, seed=EVALUATION_SEED
    )
    print(f"checkpoint: {checkpoint}")
    print(
        f"evaluate: success_rate={result['success_rate']:.3f} "
        f"reflex_rate={result['reflex_rate']:.3f} {result['reflexes_by_error'] or ''}".rstrip()
    )
    print(
        f"rllib: env_id={args.env_id} runners={args.runners} "
        f"envs_per_runner={args.envs_per_runner} env_steps_per_s={rate:.0f} "
        f"episode_return_mean={episode_return:.2f}"
    )


if __name__ == "__main__":
    main()
