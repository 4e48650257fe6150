"""Evaluate a trained policy on FrankaFCI over N episodes, all at once.

    python examples/evaluate.py --model runs/reach/model.zip --episodes 100
    python examples/evaluate.py --model runs/reach/model.zip --video runs/reach/episode.gif

Runs the N episodes side by side in the native batched env (N arms in one MuJoCo world,
arm i seeded ``seed + i``: the same episodes as N single envs;
``franka_sim_gym.training.evaluation.evaluate``), with the algorithm, env id and
arguments the model was trained with (``train_config.json`` next to the model, written
by examples/train_sb3.py; flags override it, and a model trained elsewhere, e.g. by
rl-zoo3, needs ``--algo``, ``--env-id`` and ``--env-kwargs``; its observation
normalisation, when rl-zoo3 saved one beside the model, is applied; an ensemble of
``train_bc.py --ensemble K``, listed in train_config.json, loads as one policy acting on
its members' combined action (their mean, or ``--combine upward``'s rule), acting in
the object's line frame when train_bc.py was given ``--features line``, behind the
elbow governor when train_bc.py was given ``--elbow-governor``, holding still at the
goal when it was given ``--goal-hold``; a run of
``train_sb3.py --imitation`` with the imitation policy it names). ``--model`` takes a
model.zip or its run folder. Reports the success rate,
the reflex terminations by the robot's error name, and the link's
control_command_success_rate;
ends with one line ``evaluate: success_rate=<x> reflex_rate=<y> link_success_rate=<z>``.
``--video`` renders one further episode of a single env to an animated GIF.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.training.evaluation import evaluate

#: Without a train_config.json: what train_sb3.py's first versions trained.
DEFAULT_ALGO = "sac"
DEFAULT_ENV_ID = "FrankaFCI-v0"


def record_gif(model, env_id: str, env_kwargs: dict, seed: int, path: Path) -> None:
    """One episode of a single env, rendered offscreen, saved as an animated GIF."""
    from PIL import Image  # matplotlib (the train extra) brings Pillow

    env = gym.make(env_id, render_mode="rgb_array", **env_kwargs)
    obs, _ = env.reset(seed=seed)
    frames = [env.render()]
    done = False
    while not done:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, terminated, truncated, _ = env.step(action)
        frames.append(env.render())
        done = terminated or truncated
    env.close()
    images = [Image.fromarray(f) for f in frames]
    step_ms = int(1000 / env_kwargs.get("policy_hz", gym.spec(env_id).kwargs.get("policy_hz", 25)))
    images[0].save(path, save_all=True, append_images=images[1:], duration=step_ms, loop=0)


def load_model(
    path: Path,
    algo: str | None = None,
    env_id: str | None = None,
    env_kwargs: dict | None = None,
):
    """The model and the settings it runs with: the arguments given, else those of its
    train_config.json (written by train_sb3.py next to it), else SAC on FrankaFCI-v0.

    ``path`` is the model's file or the run's folder (its model.zip). A run of
    ``train_sb3.py --imitation`` loads with the policy it named beside its actor.

    Returns (model, {"algo", "env_id", "env_kwargs"}).
    """
    import torch
    from stable_baselines3 import PPO, SAC, TD3

    from franka_sim_gym.training.ensemble import load_members
    from franka_sim_gym.training.sb3_zoo import with_normalization

    torch.set_num_threads(1)  # small networks: a thread pool costs more than it gives
    path = model_file(path)
    config = train_config(path)
    algo = algo or config.get("algo", DEFAULT_ALGO)
    env_id = env_id or config.get("env_id", DEFAULT_ENV_ID)
    env_kwargs = dict(config.get("env_kwargs", {})) if env_kwargs is None else env_kwargs
    # HER's replay buffer needs an env (for its spaces) to load the model.
    env = gym.make(env_id, **env_kwargs)
    algorithm = {"sac": SAC, "td3": TD3, "ppo": PPO}[algo]
    imitation = config.get("imitation")  # train_sb3.py --imitation's run
    if imitation is not None:
        from franka_sim_gym.training.ibrl import ImitationBootstrappedSAC

        algorithm = ImitationBootstrappedSAC
    members = config.get("members", [])  # train_bc.py --ensemble's
    model = load_members(
        path,
        members,
        lambda p: algorithm.load(p, env=env, device="cpu"),
        config.get("combine", "mean"),  # train_bc.py --combine's
    )
    # a run trained behind VecNormalize: its saved statistics, if any (an ensemble's,
    # train_bc.py's, are saved once, beside its first member, for every member)
    model = with_normalization(model, Path(path).parent / members[0] if members else path, env)
    if config.get("frame") == "line":  # train_bc.py --features line's
        from franka_sim_gym.training.line_frame import LineFrame

        model = LineFrame(model)
    if config.get("governor") == "elbow":  # train_bc.py --elbow-governor's
        from franka_sim_gym.training.governor import ElbowGovernor

        model = ElbowGovernor(model)
    goal_hold = config.get("goal_hold")  # train_bc.py --goal-hold's
    if goal_hold is not None:
        from franka_sim_gym.training.goal_hold import GoalHold

        model = GoalHold(model, **goal_hold)
    if imitation is not None:
        model.imitation, _ = load_model(Path(imitation))
    return model, {"algo": algo, "env_id": env_id, "env_kwargs": env_kwargs}


def model_file(path: str | Path) -> Path:
    """The model a path names: itself, or a run's folder's model.zip (train_sb3.py's and
    train_bc.py's --out); a FileNotFoundError naming what is missing."""
    path = Path(path)
    if path.is_dir():
        if not (path / "model.zip").is_file():
            raise FileNotFoundError(f"{path} is a folder without a model.zip")
        return path / "model.zip"
    if not path.exists() and not path.with_suffix(".zip").is_file():  # SB3 adds .zip
        raise FileNotFoundError(f"{path}: no such run folder or model.zip")
    return path


def train_config(model_path: str | Path) -> dict:
    """train_sb3.py's ``train_config.json`` next to the model ({} when there is none)."""
    config_path = Path(model_path).parent / "train_config.json"
    return json.loads(config_path.read_text()) if config_path.exists() else {}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--model",
        type=Path,
        required=True,
        help="model.zip of train_sb3.py or train_bc.py, or their run folder",
    )
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=20_000)
    parser.add_argument(
        "--algo", default=None, choices=("sac", "td3", "ppo"), help="default: train_config.json's"
    )
    parser.add_argument("--env-id", default=None, help="default: the one the model trained on")
    parser.add_argument("--env-kwargs", default=None, help="JSON; default: the training ones")
    parser.add_argument("--video", type=Path, default=None, help="write one episode as a GIF")
    args = parser.parse_args()
    kwargs = json.loads(args.env_kwargs) if args.env_kwargs else None
    model, config = load_model(args.model, args.algo, args.env_id, kwargs)
    env_id, kwargs = config["env_id"], config["env_kwargs"]
    result = evaluate(model, env_id, kwargs, args.episodes, args.seed)
    print(f"{env_id} {kwargs}: {args.episodes} episodes")
    print(f"reflexes by error: {result['reflexes_by_error'] or 'none'}")
    if args.video:
        record_gif(model, env_id, kwargs, args.seed, args.video)
        print(f"video: {args.video}")
    print(
        f"evaluate: success_rate={result['success_rate']:.3f} "
        f"reflex_rate={result['reflex_rate']:.3f} "
        f"link_success_rate={result['link_success_rate']:.3f}"
    )


if __name__ == "__main__":
    main()
