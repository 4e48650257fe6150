"""Where a manipulation policy fails: per episode, how it ended and in which phase.

    python examples/where_it_fails.py --model runs/push/model.zip --episodes 100

Runs the saved model (examples/evaluate.py's loading: train_config.json, the
normalisation beside it) on N episodes side by side, seeds 10,000 on (the training
runs' evaluation episodes), and sorts every episode by how it ended: success; a
reflex, with the robot's error names, the step, the TCP's height above the table, and
whether the object had moved yet (> 1 cm from its start: for Push and PickAndPlace,
before or after the hand reached it; the held peg moves with the hand), and where the
achieved goal was (the object's centre, the peg's tip) relative to the goal (the
hole's bottom for PegInsertion); or the time limit with the object's last distance to
its goal.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import gymnasium as gym
import numpy as np

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.training.evaluation import EVALUATION_SEED

#: the TCP position in the observation (docs/env.md, "Observations")
EE = slice(14, 17)


def run(policy, env_id: str, env_kwargs: dict, episodes: int, seed: int) -> list[dict]:
    """One deterministic episode per arm; a row per episode (see the module's doc)."""
    envs = gym.make_vec(
        env_id, num_envs=episodes, vectorization_mode="vector_entry_point", **env_kwargs
    )
    obs, _ = envs.reset(seed=seed)
    at = obs["observation"].shape[1] - 13  # the object's entries come last
    start = obs["observation"][:, at : at + 3].copy()
    rows: list[dict | None] = [None] * episodes
    step = 0
    while any(r is None for r in rows):
        actions, _ = policy.predict(obs, deterministic=True)
        before = obs
        obs, _, terminated, truncated, info = envs.step(actions)
        step += 1
        for i in np.flatnonzero(terminated | truncated).tolist():
            if rows[i] is not None:
                continue
            last = before if terminated[i] else obs  # (a reflex's final obs is the reset's)
            o = last["observation"][i]
            offset = last["achieved_goal"][i] - last["desired_goal"][i]
            row = {
                "step": step,
                "tcp_z": float(o[EE][2]),
                "object_moved": float(np.linalg.norm(o[at : at + 2] - start[i, :2])),
                "goal_distance": float(np.linalg.norm(offset)),
                "goal_xy": float(np.linalg.norm(offset[:2])),
                "goal_dz": float(offset[2]),
            }
            if terminated[i]:
                row["end"] = "reflex"
                row["errors"] = tuple(info["reflex_reason"][i])
            else:
                row["end"] = "success" if info["is_success"][i] else "time limit"
            rows[i] = row
    envs.close()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, required=True, help="a model.zip or its run folder")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=EVALUATION_SEED)
    args = parser.parse_args()
    from evaluate import load_model

    model, config = load_model(args.model)
    rows = run(model, config["env_id"], config["env_kwargs"], args.episodes, args.seed)
    ends = Counter(r["end"] for r in rows)
    print(f"{config['env_id']}: {dict(ends)}")
    reflexes = [r for r in rows if r["end"] == "reflex"]
    if reflexes:
        phases = Counter(
            ("before the object moved" if r["object_moved"] < 0.01 else "object moving")
            for r in reflexes
        )
        names = Counter(name for r in reflexes for name in r["errors"])
        print(f"reflexes: {dict(names)}; {dict(phases)}")
        print(
            "  medians at the reflex: step {:.0f}, TCP height {:.3f} m, achieved goal "
            "{:.3f} m off the goal in xy and {:+.3f} m in z".format(
                *(
                    np.median([r[k] for r in reflexes])
                    for k in ("step", "tcp_z", "goal_xy", "goal_dz")
                )
            )
        )
    late = [r for r in rows if r["end"] == "time limit"]
    if late:
        print(
            "time limit: object moved (median) {:.3f} m, left {:.3f} m from its goal".format(
                np.median([r["object_moved"] for r in late]),
                np.median([r["goal_distance"] for r in late]),
            )
        )


if __name__ == "__main__":
    main()
