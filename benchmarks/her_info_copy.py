"""What the env's infos cost SB3's HER replay buffer when it copies them (rl-zoo3's file).

    pip install rl_zoo3        # (its PyYAML reads the shipped file)
    python benchmarks/her_info_copy.py [--samples N] [--draws D] [--repeats R]

The shipped rl-zoo3 file (franka_sim_gym/training/hyperparams/sac.yml) trains with SB3's
``HerReplayBuffer(copy_info_dict=True)``, which deep-copies the stored info of every
relabelled transition at every gradient step (4 of 5 of a batch of 256), so that the
reflex charge survives relabelling (docs/training.md). The buffer is filled as rl-zoo3
fills it without the file's BatchedArms (16 single envs in SB3's DummyVecEnv, Monitor,
the entry's env arguments, random actions, N samples); then D draws of a batch of 256
are timed three ways on the same buffer and the same draws:

* the infos as the env gives them (``envs.infos.InfoRow``, whose deep copy skips the
  immutable entries);
* the same infos as plain dicts (the deep copy every entry gets);
* ``copy_info_dict=False`` (no infos copied: the floor).

Prints ms per draw (best of R) and the ratio to bare mj_step of the one-arm world in the
same run; and whether both copies gave the same batches' rewards.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
import smoke  # benchmarks/smoke.py: --smoke
import yaml
from stable_baselines3 import HerReplayBuffer
from stable_baselines3.common.env_util import make_vec_env

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.training import hyperparams_file
from franka_sim_gym.training.sb3_zoo import entry_env_kwargs

ENV_ID = "FrankaFCICartesianVelocity-v0"


def draws(buffer: HerReplayBuffer, env, count: int, seed: int) -> tuple[float, np.ndarray]:
    """ms per ``sample(256)`` over ``count`` draws, and the rewards drawn."""
    np.random.seed(seed)  # HER draws with numpy's global generator
    rewards = []
    start = time.perf_counter()
    for _ in range(count):
        rewards.append(buffer.sample(256, env=None).rewards.numpy())
    return (time.perf_counter() - start) / count * 1e3, np.concatenate(rewards)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1600, help="transitions in the buffer")
    parser.add_argument("--draws", type=int, default=200, help="batches drawn per timing")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--arms", type=int, default=None, help="envs (default: the file's)")
    parser.add_argument(
        "--bare-seconds", type=float, default=1.0, help="time of the bare mj_step row"
    )
    args = smoke.parse_args(parser, samples=50, draws=3, repeats=1, bare_seconds=0.1, arms=2)
    settings = yaml.safe_load(hyperparams_file("sac").read_text())[ENV_ID]
    arms = args.arms or settings["n_envs"]
    env = make_vec_env(ENV_ID, n_envs=arms, seed=0, env_kwargs=entry_env_kwargs(settings))
    buffer = HerReplayBuffer(
        args.samples + arms,
        env.observation_space,
        env.action_space,
        env=env,
        n_envs=arms,
        goal_selection_strategy="future",
        n_sampled_goal=4,
        copy_info_dict=True,
    )
    rng = np.random.default_rng(0)
    obs = env.reset()
    for _ in range(args.samples // arms):
        action = rng.uniform(-1, 1, (arms, *env.action_space.shape)).astype(np.float32)
        next_obs, reward, done, infos = env.step(action)
        buffer.add(obs, next_obs, action, reward, done, infos)
        obs = next_obs
    rows = buffer.infos
    as_env = rows.copy()
    as_dicts = np.empty_like(rows)
    for index in np.ndindex(rows.shape):
        as_dicts[index] = dict(rows[index]) if rows[index] is not None else None
    kind = type(next(r for r in rows.flat if r is not None)).__name__
    best: dict[str, float] = {}
    drawn: dict[str, np.ndarray] = {}
    for _ in range(args.repeats):
        for name, infos, copy_info in (
            (f"infos as the env gives them ({kind})", as_env, True),
            ("infos as plain dicts", as_dicts, True),
            ("copy_info_dict=False", as_env, False),
        ):
            buffer.infos, buffer.copy_info_dict = infos, copy_info
            ms, drawn[name] = draws(buffer, env, args.draws, seed=1)
            best[name] = min(ms, best.get(name, ms))
    physics = ArmPhysics(n_arms=1)
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < args.bare_seconds:
        for _ in range(100):
            mujoco.mj_step(physics.model, physics.data)
        calls += 100
    bare = (time.perf_counter() - start) / calls * 1e3
    names = list(best)
    same = np.array_equal(drawn[names[0]], drawn[names[1]])
    print(describe())
    print(f"{args.samples} transitions, {args.draws} draws of 256, best of {args.repeats}")
    print(f"{'row':<44}{'ms/draw':>10}{'vs mj_step':>12}")
    print(f"{'bare mj_step (one arm)':<44}{bare:>10.4f}{1.0:>12.0f}")
    for name, ms in best.items():
        print(f"{name:<44}{ms:>10.3f}{ms / bare:>12.0f}")
    print(f"same rewards drawn with both copies: {'yes' if same else 'NO'}")
    print(
        f"summary: env_infos_ms={best[names[0]]:.3f} dict_infos_ms={best[names[1]]:.3f} "
        f"no_copy_ms={best[names[2]]:.3f} same={int(same)}"
    )


if __name__ == "__main__":
    main()
