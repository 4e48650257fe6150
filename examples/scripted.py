"""Scripted solvers for the manipulation tasks: the proof that each is solvable under the
robot's rules, and a baseline for learners.

    python examples/scripted.py --env-id FrankaFCIPush-v0 --episodes 200
    python examples/scripted.py --env-id FrankaFCIPush-v0 --episodes 200 --naive

Each solver is what a user would write against the env's public action interface: it
reads the observation (docs/env.md lays it out) and sends Cartesian velocities (and the
hand's width), nothing else. It keeps its contact forces under the robot's collision
thresholds by staying clear of the table and by pushing, placing and inserting slowly.
``--naive`` is the same solver with those limits removed: full speed, and no floor
above the table — the robot's reflexes then end episodes, as they would on an FR3.

Episodes run side by side in the native batched env (episode i seeded ``seed + i``,
the same episodes as single envs). Last line:
``scripted: env_id=ID success_rate=x reflex_rate=y``.
"""

from __future__ import annotations

import argparse
from collections import Counter

import gymnasium as gym
import numpy as np

import franka_sim_gym  # noqa: F401  (registers the ids)

#: observation layout (docs/env.md): q 0:7, dq 7:14, O_T_EE position 14:17, twist 17:23,
#: then [the hand's width], then the object's position, quaternion, velocities.
EE = slice(14, 17)
#: Cartesian velocity of an action of 1.0 [m/s] (docs/env.md, "Actions").
SPEED_SCALE = 0.3
#: The block's half size [m].
HALF = 0.02


class Limits:
    """What keeps a solver's contacts gentle: its speed caps and its floor above the table."""

    def __init__(self, naive: bool) -> None:
        self.naive = naive
        #: free-space speed [m/s]
        self.travel = SPEED_SCALE if naive else 0.25
        #: descent speed onto the work height [m/s]
        self.descend = SPEED_SCALE if naive else 0.15
        #: speed while in contact (pushing, placing, inserting) [m/s]
        self.contact = SPEED_SCALE if naive else 0.12
        #: the lowest TCP height commanded [m]: the closed fingertips reach 9 mm below it
        self.floor = -0.05 if naive else 0.016
        #: position gain [1/s]
        self.gain = 30.0 if naive else 5.0


def velocity_towards(ee, target, speed, gain):
    """(n, 3) a velocity [m/s] that moves ``ee`` to ``target``, capped at ``speed``."""
    v = gain * (target - ee)
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    return v * np.minimum(1.0, np.asarray(speed).reshape(-1, 1) / np.maximum(norm, 1e-9))


class PushSolver:
    """Behind the block on the line through it and the goal, down, then push along it;
    back up and around when the block drifts off the line."""

    #: TCP height for travelling over the block [m] (fingertips 3 cm above its top)
    HIGH = 0.06
    #: TCP height for pushing: fingertips 1 cm above the table, at the block's middle
    LOW = 0.033
    #: how far behind the block's centre the TCP lines up [m]
    STANDOFF = HALF + 0.035

    def __init__(self, n: int, limits: Limits, object_at: int) -> None:
        self.limits = limits
        self.object_at = object_at
        self.phase = np.zeros(n, dtype=np.int64)  # 0 over, 1 down, 2 push

    def reset(self, arms) -> None:
        self.phase[arms] = 0

    def act(self, obs: dict) -> np.ndarray:
        lim = self.limits
        o = obs["observation"]
        ee = o[:, EE].astype(np.float64)
        block = o[:, self.object_at : self.object_at + 3].astype(np.float64)
        goal = obs["desired_goal"].astype(np.float64)
        line = goal[:, :2] - block[:, :2]
        far = np.linalg.norm(line, axis=1)
        d = line / np.maximum(far, 1e-9)[:, None]
        behind = block[:, :2] - d * self.STANDOFF
        low = max(self.LOW, lim.floor) if not lim.naive else lim.floor
        # Where the TCP is relative to the push line: along it and off it.
        rel = ee[:, :2] - block[:, :2]
        along = np.sum(rel * d, axis=1)
        off = np.abs(rel[:, 0] * d[:, 1] - rel[:, 1] * d[:, 0])
        lined_up = np.linalg.norm(ee[:, :2] - behind, axis=1) < 0.01
        # phase changes
        self.phase[(self.phase == 0) & lined_up] = 1
        twist = o[:, 17:20].astype(np.float64)  # the commanded velocity
        settled = (np.abs(ee[:, 2] - low) < 0.003) & (np.linalg.norm(twist, axis=1) < 0.02)
        self.phase[(self.phase == 1) & settled] = 2
        lost = (self.phase == 2) & ((off > 0.025) | (along > -HALF))
        self.phase[lost] = 0
        target = np.empty_like(ee)
        speed = np.full(len(ee), lim.travel)
        over = self.phase == 0
        # Over: up first, then across (never sweep through the block).
        high_enough = ee[:, 2] > self.HIGH - 0.01
        target[over, :2] = np.where(high_enough[over, None], behind[over], ee[over, :2])
        target[over, 2] = self.HIGH
        down = self.phase == 1
        target[down, :2] = behind[down]
        target[down, 2] = low
        speed[down] = lim.descend
        push = self.phase == 2
        target[push] = ee[push]  # (the velocity is set below)
        done = far < 0.01
        target[done] = ee[done]
        v = velocity_towards(ee, target, speed, lim.gain)
        # Pushing: along the line at the contact speed (slowing into the goal), steered
        # back onto the line behind the block, the height held.
        side = behind - ee[:, :2]
        side -= np.sum(side * d, axis=1, keepdims=True) * d
        forward = np.minimum(lim.contact, lim.gain * far)[:, None] * d
        steer = lim.gain * side
        steer *= np.minimum(
            1.0, 0.5 * lim.contact / np.maximum(np.linalg.norm(steer, axis=1), 1e-9)
        )[:, None]
        v_push = np.concatenate([forward + steer, lim.gain * (low - ee[:, 2:3])], 1)
        rows = push & ~done
        v[rows] = v_push[rows]
        return np.clip(v / SPEED_SCALE, -1.0, 1.0).astype(np.float32)


SOLVERS = {"Push": PushSolver}


def solver_for(env_id: str, n: int, naive: bool, object_at: int):
    """The solver of ``env_id``'s task (its ``id_name``)."""
    spec = gym.spec(env_id)
    task = franka_sim_gym.envs.tasks.TASKS[spec.kwargs["task"]]
    if task.id_name not in SOLVERS:
        raise SystemExit(f"no scripted solver for {env_id} (tasks: {sorted(SOLVERS)})")
    return SOLVERS[task.id_name](n, Limits(naive), object_at)


def run(env_id: str, episodes: int, seed: int = 0, naive: bool = False, batch: int = 50):
    """Run ``episodes`` seeded episodes; returns (success rate, reflex rate, reflexes)."""
    successes, reflexes, reasons = 0, 0, Counter()
    for start in range(0, episodes, batch):
        n = min(batch, episodes - start)
        envs = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
        space = envs.single_observation_space["observation"]
        object_at = space.shape[0] - 13  # the object's 13 entries come last
        solver = solver_for(env_id, n, naive, object_at)
        obs, _ = envs.reset(seed=seed + start)
        solver.reset(np.arange(n))
        running = np.ones(n, dtype=bool)
        while running.any():
            obs, _, terminated, truncated, info = envs.step(solver.act(obs))
            ended = running & (terminated | truncated)
            for i in np.flatnonzero(ended).tolist():
                successes += bool(info["is_success"][i])
                if terminated[i]:
                    reflexes += 1
                    reasons.update(info["reflex_reason"][i])
            running &= ~ended
        envs.close()
    return successes / episodes, reflexes / episodes, reasons


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="FrankaFCIPush-v0")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--naive", action="store_true", help="no speed caps, no floor")
    parser.add_argument("--batch", type=int, default=50, help="arms per batched env")
    args = parser.parse_args()
    success, reflex, reasons = run(args.env_id, args.episodes, args.seed, args.naive, args.batch)
    if reasons:
        print("reflexes:", ", ".join(f"{name} {count}" for name, count in reasons.most_common()))
    print(f"scripted: env_id={args.env_id} success_rate={success:.3f} reflex_rate={reflex:.3f}")


if __name__ == "__main__":
    main()
