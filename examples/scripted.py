"""Scripted solvers for the manipulation tasks: the proof that each is solvable under the
robot's rules, and a baseline for learners.

    python examples/scripted.py --env-id FrankaFCIPush-v0 --episodes 200
    python examples/scripted.py --env-id FrankaFCIPush-v0 --episodes 200 --naive
    python examples/scripted.py --env-id FrankaFCIPush-v0 --episodes 50 \
        --env-kwargs '{"policy_hz": 10, "max_episode_steps": 40}' --record franka/push-v0

Each solver is what a user would write against the env's public action interface: it
reads the observation (docs/env.md lays it out) and sends Cartesian velocities (and the
hand's width), nothing else. It keeps its contact forces under the robot's collision
thresholds by staying clear of the table and by pushing, placing and inserting slowly.
``--naive`` is the same solver with those limits removed: full speed, and no floor
above the table — the robot's reflexes then end episodes, as they would on an FR3.

Episodes run side by side in the native batched env (episode i seeded ``seed + i``,
the same episodes as single envs). Last line:
``scripted: env_id=ID success_rate=x reflex_rate=y``. ``--env-kwargs`` (JSON) are
passed to the env (e.g. another policy rate and episode length).

``--record DATASET_ID`` stores the episodes as a Minari dataset (the ``datasets``
extra; ``$MINARI_DATASETS_PATH`` or Minari's default directory) through
``franka_sim_gym.training.datasets.record``: observations, actions, rewards, the
infos, each episode's seed and the env's spec (docs/demonstrations.md). With
``--noise SIGMA`` the recorded episodes are noise-injected (DART): each step the
solver's TCP velocity plus Gaussian noise of standard deviation SIGMA (in action
units, 1.0 = 0.3 m/s) on each of its three axes is executed, and the solver's own action
is stored beside it as the label a learner imitates (Push: 0.1; PickAndPlace, whose
grasp lines up to 5 mm: 0.05; PegInsertion, whose insertion runs at 0.02 m/s: 0.03;
docs/demonstrations.md).
"""

from __future__ import annotations

import argparse
import json
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
#: Closer to the base than this (x, m) at table height the FR3's elbow nears its stop
#: (joint 4 beyond -2.9 rad): a fast motion there trips the robot's
#: joint_velocity_violation, so the solvers go slowly.
NEAR_BASE = 0.36
#: ... and no target closer than this (joint 4 reaches -3.0 rad there).
CLOSEST = 0.30


class Limits:
    """What keeps a solver's contacts gentle: its speed caps and its floor above the table."""

    def __init__(self, naive: bool) -> None:
        self.naive = naive
        #: free-space speed [m/s]
        self.travel = SPEED_SCALE if naive else 0.25
        #: descent speed onto the work height [m/s]
        self.descend = SPEED_SCALE if naive else 0.15
        #: speed while in contact (pushing; placing and inserting go slower) [m/s]
        self.contact = SPEED_SCALE if naive else 0.22
        #: the lowest TCP height commanded [m]: the closed fingertips reach 9 mm below it
        self.floor = -0.05 if naive else 0.016
        #: position gain [1/s]
        self.gain = 30.0 if naive else 8.0
        #: speed carrying a held block [m/s]
        self.carry = SPEED_SCALE if naive else 0.2


def velocity_towards(ee, target, speed, gain):
    """(n, 3) a velocity [m/s] that moves ``ee`` to ``target``, capped at ``speed``."""
    v = gain * (target - ee)
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    return v * np.minimum(1.0, np.asarray(speed).reshape(-1, 1) / np.maximum(norm, 1e-9))


class PushSolver:
    """Behind the block on the line through it and the goal, down, then push along it;
    back up and around when the block drifts off the line.

    Its action is a function of the observation alone: the phase (over, down, push) is
    read off each observation, not kept from the last one. A learner sees only the
    observation, so a kept phase would give one observation two labels, and DAgger's
    labels of a learner's states (examples/train_bc.py --dagger) would depend on how the
    learner got there (docs/demonstrations.md, "DAgger")."""

    #: TCP height for travelling over the block [m]: 3.2 cm above its top, a margin a
    #: clone's height error does not eat (at 6 cm, crossing from 5 cm, its fingers met
    #: the block's edge: docs/demonstrations.md, "Push: what else was tried")
    HIGH = 2 * HALF + 0.032
    #: it crosses over the block only once within this of its travel height [m]
    CROSS = 0.003
    #: TCP height for pushing: fingertips 1 cm above the table, at the block's middle
    LOW = 0.033
    #: how far behind the block's centre the TCP lines up [m]
    STANDOFF = HALF + 0.035
    #: within this of the lining-up point (across) it goes down [m]
    LINED_UP = 0.01
    # It pushes where the TCP is down in the corridor behind the block
    # (docs/demonstrations.md, "Push: the closest it comes"):
    #: the corridor's half width about the line [m] (the block's half size)
    CORRIDOR = 0.02
    #: ... and its length, from the block's back face to this far behind the
    #: lining-up point [m]
    CORRIDOR_BACK = 0.015
    #: down, at the lining-up point (until this far on from it [m]) ...
    STARTED = 0.01
    #: ... is within this of the pushing height [m] ...
    DOWN_BAND = 0.003
    #: ... with the commanded vertical speed under this [m/s]: settled (pushing within
    #: 6 mm, settled or not, met the table: alone 0.85 success, 0.195 reflexes)
    SETTLED = 0.02
    #: down, nearer the block, is within this [m]: with the 3 mm and the settling
    #: everywhere, the noise-injected demonstrations (noise 0.1) succeeded 0.36-0.50
    HELD_BAND = 0.008

    def __init__(self, n: int, limits: Limits, object_at: int) -> None:
        self.limits = limits
        self.object_at = object_at

    def reset(self, arms) -> None:
        """Nothing to reset: the solver keeps no state between steps."""

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
        if not lim.naive:  # no closer to the base than the elbow allows at speed
            behind[:, 0] = np.maximum(behind[:, 0], CLOSEST)
        low = max(self.LOW, lim.floor) if not lim.naive else lim.floor
        # Where the TCP is relative to the push line: along it and off it.
        rel = ee[:, :2] - block[:, :2]
        along = np.sum(rel * d, axis=1)
        off = np.abs(rel[:, 0] * d[:, 1] - rel[:, 1] * d[:, 0])
        lined_up = np.linalg.norm(ee[:, :2] - behind, axis=1) < self.LINED_UP
        twist = o[:, 17:20].astype(np.float64)  # the commanded velocity
        height = np.abs(ee[:, 2] - low)
        at_start = along < -(self.STANDOFF - self.STARTED)
        down_here = np.where(
            at_start,
            (height < self.DOWN_BAND) & (np.abs(twist[:, 2]) < self.SETTLED),
            height < self.HELD_BAND,
        )
        corridor = (off < self.CORRIDOR) & (along < -HALF)
        corridor &= along > -(self.STANDOFF + self.CORRIDOR_BACK)
        push = down_here & corridor
        down = ~push & lined_up
        over = ~push & ~down
        target = np.empty_like(ee)
        speed = np.full(len(ee), lim.travel)
        # Over: up first, then across (never sweep through the block); already low and
        # behind the block on the new line: straight there.
        high_enough = ee[:, 2] > self.HIGH - self.CROSS
        target[over, :2] = np.where(high_enough[over, None], behind[over], ee[over, :2])
        target[over, 2] = self.HIGH
        stay_low = over & ~high_enough & (along < -(HALF + 0.025))
        target[stay_low, :2] = behind[stay_low]
        target[stay_low, 2] = low
        target[down, :2] = behind[down]
        target[down, 2] = low
        speed[down] = lim.descend
        target[push] = ee[push]  # (the velocity is set below)
        done = far < 0.01
        target[done] = ee[done]
        if not lim.naive:  # slowly near the base, where the elbow folds to its stop
            near = (ee[:, 0] < NEAR_BASE) | (target[:, 0] < NEAR_BASE)
            speed[near] = np.minimum(speed[near], 0.15)
            speed[near & down] = np.minimum(speed[near & down], 0.06)  # the descent
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


class PickAndPlaceSolver:
    """Open above the block, down around it, close (the hand squeezes it with the env's
    grasp force), up, across at a safe height, down to the goal; start over if it drops.
    A goal on the table is let go of just above it and left from above.

    Its gates are ones a learner cloned from it can see in the observation: it goes down
    to grasp only while lined up over the block, and slowly for the last centimetre;
    it closes as soon as the hand is at grasp height, with no wait to settle; it goes
    down to a goal from 3 cm off it (docs/demonstrations.md, "PickAndPlace: a solver a
    clone can follow")."""

    HIGH = 0.08  # TCP height for travelling [m]
    #: TCP height at which a held block (its centre on the TCP) clears the table
    CARRY = 0.07
    #: TCP height of the grasp [m]: 5 mm above the block's centre, so a descent that
    #: overshoots a few millimetres does not press the fingertips onto the table
    GRASP = HALF + 0.005
    #: the hand closes once this close above the grasp height [m] (no wait to settle)
    CLOSE = 0.004
    #: how far off the block's centre (across) the hand may be while going down [m]
    ALIGN = 0.005
    #: grasp descent [m/s]: the block's width between open fingers leaves 2 cm a side
    DESCEND = 0.12
    #: ... and within this of the grasp height [m], this slower [m/s]
    LAST, SLOW = 0.01, 0.04
    #: how far from the goal (across) the held block starts down to it [m]
    NEAR_GOAL = 0.03
    #: a goal is on the table when this close to the block's resting height [m]
    ON_TABLE = 0.005
    #: the held block's centre this far above a table goal is let go of [m]
    DROP = 0.008

    def __init__(self, n: int, limits: Limits, object_at: int) -> None:
        self.limits = limits
        self.object_at = object_at
        # 0 over, 1 down, 2 close, 3 carry, 4 let go and rise
        self.phase = np.zeros(n, dtype=np.int64)

    def reset(self, arms) -> None:
        self.phase[arms] = 0

    def act(self, obs: dict) -> np.ndarray:
        lim = self.limits
        o = obs["observation"].astype(np.float64)
        ee, width = o[:, EE], o[:, self.object_at - 1]
        block = o[:, self.object_at : self.object_at + 3]
        goal = obs["desired_goal"].astype(np.float64)
        grasp_z = max(self.GRASP, lim.floor) if not lim.naive else lim.floor
        across = np.linalg.norm(ee[:, :2] - block[:, :2], axis=1)
        aligned = across < self.ALIGN
        p = self.phase
        p[(p == 0) & aligned & (ee[:, 2] > self.HIGH - 0.01) & (width > 0.075)] = 1
        p[(p == 1) & (ee[:, 2] < grasp_z + self.CLOSE)] = 2
        p[(p == 2) & (width < 2 * HALF + 0.0015)] = 3  # the fingers have met the block
        to_goal = np.linalg.norm(goal[:, :2] - ee[:, :2], axis=1)
        on_table = goal[:, 2] < HALF + self.ON_TABLE
        p[(p == 3) & on_table & (to_goal < 0.01) & (block[:, 2] < goal[:, 2] + self.DROP)] = 4
        held = np.linalg.norm(block - ee, axis=1) < 0.03
        dropped = (p == 3) & ~held
        p[dropped] = 0
        # let go of and risen clear of a block that is not at its goal: start over
        missed = (p == 4) & (ee[:, 2] > self.HIGH - 0.01)
        missed &= np.linalg.norm(block - goal, axis=1) > 0.02
        p[missed] = 0
        target = ee.copy()
        speed = np.full(len(ee), lim.travel)
        hand = np.ones(len(ee))  # open
        rows = p == 0
        high = ee[:, 2] > self.HIGH - 0.01
        target[rows, :2] = np.where(high[rows, None], block[rows, :2], ee[rows, :2])
        target[rows, 2] = self.HIGH
        rows = p == 1
        target[rows, :2] = block[rows, :2]
        # down only while lined up over the block; else hold the height and line up
        target[rows, 2] = np.where(aligned[rows], grasp_z, ee[rows, 2])
        last = ee[:, 2] < grasp_z + self.LAST
        slow = np.where(last[rows], self.SLOW, min(self.DESCEND, lim.descend))
        speed[rows] = lim.descend if lim.naive else slow
        rows = p == 2
        hand[rows] = -1.0
        rows = p == 3
        hand[rows] = -1.0
        lifted = ee[:, 2] > self.CARRY - 0.01
        near = to_goal < self.NEAR_GOAL
        up = rows & ~near & ~lifted
        target[up, 2] = self.CARRY
        travel = rows & ~near & lifted
        target[travel, :2] = goal[travel, :2]
        target[travel, 2] = np.maximum(goal[travel, 2], self.CARRY)
        there = rows & near
        target[there] = goal[there]
        speed[rows] = lim.carry
        rows = p == 4  # open, and rise straight up
        target[rows, 2] = self.HIGH
        v = velocity_towards(ee, target, speed, lim.gain)
        return np.concatenate([np.clip(v / SPEED_SCALE, -1, 1), hand[:, None]], 1).astype(
            np.float32
        )


def rotation_of(quat: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices of (n, 4) unit quaternions w, x, y, z."""
    w, x, y, z = quat.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """(n, 3) the rotation vectors (axis times angle) of (n, 3, 3) small rotations."""
    angle = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1))
    axis = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], 1)
    scale = np.where(angle > 1e-9, angle / np.maximum(2 * np.sin(angle), 1e-12), 0.5)
    return axis * scale[:, None]


class PegInsertionSolver:
    """Turn the peg upright and square to the hole, bring its tip over the hole, then
    lower it slowly, steering its tip onto the hole's axis, until it reaches the bottom."""

    HALF_LENGTH = 0.04  # the peg's [m]
    ABOVE = 0.04  # tip height over the hole before inserting (fixture top: 0.03) [m]
    #: speed of the approach over the hole, and of the insertion [m/s]
    APPROACH, INSERT = 0.12, 0.02
    #: angular speed cap [rad/s] and the angular velocity of an action of 1.0
    TURN, TURN_SCALE = 0.3, 0.5

    def __init__(self, n: int, limits: Limits, object_at: int) -> None:
        self.limits = limits
        self.object_at = object_at
        self.phase = np.zeros(n, dtype=np.int64)  # 0 align, 1 insert

    def reset(self, arms) -> None:
        self.phase[arms] = 0

    def act(self, obs: dict) -> np.ndarray:
        lim = self.limits
        o = obs["observation"].astype(np.float64)
        at = self.object_at
        R = rotation_of(o[:, at + 3 : at + 7])
        tip = o[:, at : at + 3] - self.HALF_LENGTH * R[:, :, 2]
        hole = obs["desired_goal"].astype(np.float64)
        # The square peg is square to the hole at any quarter turn: aim for the nearest.
        yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
        yaw = np.round(yaw / (np.pi / 2)) * (np.pi / 2)
        c, s_ = np.cos(yaw), np.sin(yaw)
        target_R = np.zeros_like(R)
        target_R[:, 0, 0], target_R[:, 0, 1], target_R[:, 1, 0], target_R[:, 1, 1] = c, -s_, s_, c
        target_R[:, 2, 2] = 1.0
        error = rotation_vector(target_R @ np.transpose(R, (0, 2, 1)))
        omega = 3.0 * error
        norm = np.linalg.norm(omega, axis=1, keepdims=True)
        omega *= np.minimum(1.0, self.TURN / np.maximum(norm, 1e-9))
        xy_error = np.linalg.norm(hole[:, :2] - tip[:, :2], axis=1)
        above = hole.copy()
        above[:, 2] = self.ABOVE
        twist = np.linalg.norm(o[:, 17:20], axis=1)
        ready = (xy_error < 0.0005) & (np.abs(tip[:, 2] - self.ABOVE) < 0.003)
        ready &= (np.linalg.norm(error, axis=1) < 0.01) & (twist < 0.01)
        self.phase[(self.phase == 0) & ready] = 1
        approach = SPEED_SCALE if lim.naive else self.APPROACH
        v = velocity_towards(tip, above, np.full(len(tip), approach), lim.gain)
        inserting = self.phase == 1
        if lim.naive:  # straight down at full speed
            v[inserting] = [0.0, 0.0, -SPEED_SCALE]
        else:
            down = np.minimum(self.INSERT, lim.gain * np.maximum(tip[:, 2] - 0.0005, 0.0))
            steer = lim.gain * (hole[:, :2] - tip[:, :2])
            v[inserting, :2] = steer[inserting]
            v[inserting, 2] = -down[inserting]
        action = np.concatenate([v / SPEED_SCALE, omega / self.TURN_SCALE], axis=1)
        return np.clip(action, -1, 1).astype(np.float32)


SOLVERS = {
    "Push": PushSolver,
    "PickAndPlace": PickAndPlaceSolver,
    "PegInsertion": PegInsertionSolver,
}


def solver_for(env_id: str, n: int, naive: bool, object_at: int):
    """The solver of ``env_id``'s task (its ``id_name``)."""
    spec = gym.spec(env_id)
    task = franka_sim_gym.envs.tasks.TASKS[spec.kwargs["task"]]
    if task.id_name not in SOLVERS:
        raise SystemExit(f"no scripted solver for {env_id} (tasks: {sorted(SOLVERS)})")
    return SOLVERS[task.id_name](n, Limits(naive), object_at)


class ScriptedPolicy:
    """A solver as the policy ``franka_sim_gym.training.datasets.record`` takes: called
    on a batch of observations; ``reset(arms)`` starts a batch of that many arms."""

    def __init__(self, env_id: str, naive: bool = False, env_kwargs: dict | None = None):
        env = gym.make(env_id, **(env_kwargs or {}))
        self.object_at = env.observation_space["observation"].shape[0] - 13
        self.action_dim = env.action_space.shape[0]
        env.close()
        self.env_id, self.naive = env_id, naive
        self.solver = None

    def translation_noise(self, sigma: float) -> list[float] | None:
        """``sigma`` on the action's three TCP-velocity axes, 0 on the rest (the hand's
        width, the angular velocity); None for no noise."""
        return [sigma] * 3 + [0.0] * (self.action_dim - 3) if sigma else None

    def reset(self, arms: np.ndarray) -> None:
        self.solver = solver_for(self.env_id, len(arms), self.naive, self.object_at)

    def __call__(self, obs: dict) -> np.ndarray:
        return self.solver.act(obs)


def run(
    env_id: str,
    episodes: int,
    seed: int = 0,
    naive: bool = False,
    batch: int = 50,
    env_kwargs: dict | None = None,
):
    """Run ``episodes`` seeded episodes; returns (success rate, reflex rate, reflexes)."""
    successes, reflexes, reasons = 0, 0, Counter()
    for start in range(0, episodes, batch):
        n = min(batch, episodes - start)
        envs = gym.make_vec(
            env_id, num_envs=n, vectorization_mode="vector_entry_point", **(env_kwargs or {})
        )
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
    parser.add_argument("--env-kwargs", default="{}", help="JSON: arguments of the env")
    parser.add_argument(
        "--record", metavar="DATASET_ID", help="store the episodes as this Minari dataset"
    )
    parser.add_argument(
        "--noise",
        type=float,
        default=0.0,
        metavar="SIGMA",
        help="with --record: Gaussian noise on the executed TCP velocity (action units)",
    )
    args = parser.parse_args()
    env_kwargs = json.loads(args.env_kwargs)
    if args.noise and not args.record:
        parser.error("--noise records noise-injected demonstrations: give --record too")
    if args.record:
        from franka_sim_gym.training.datasets import record, summary

        policy = ScriptedPolicy(args.env_id, args.naive, env_kwargs)
        dataset = record(
            args.record,
            args.env_id,
            policy,
            args.episodes,
            seed=args.seed,
            env_kwargs=env_kwargs,
            num_envs=args.batch,
            algorithm_name="examples/scripted.py"
            + (" --naive" if args.naive else "")
            + (f" --noise {args.noise}" if args.noise else ""),
            description=f"scripted solver of {args.env_id}"
            + (f", noise-injected (sigma {args.noise} on the TCP velocity)" if args.noise else ""),
            noise=policy.translation_noise(args.noise),
        )
        success, reflex, reasons = summary(dataset)
        print(f"recorded {dataset.total_episodes} episodes as {args.record}")
    else:
        success, reflex, reasons = run(
            args.env_id, args.episodes, args.seed, args.naive, args.batch, env_kwargs
        )
    if reasons:
        print("reflexes:", ", ".join(f"{name} {count}" for name, count in reasons.most_common()))
    print(f"scripted: env_id={args.env_id} success_rate={success:.3f} reflex_rate={reflex:.3f}")


if __name__ == "__main__":
    main()
