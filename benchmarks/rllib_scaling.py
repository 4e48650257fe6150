"""RLlib sampling throughput by runners x batched arms: 1x1, 2x1, 1xN, 2xN in one run.

    pip install 'franka-sim-gym[rllib]'
    python benchmarks/rllib_scaling.py [--arms N] [--steps S] [--repeats R] [--seconds T]

examples/train_rllib.py's PPO configuration (the env named so that remote runners find
it, the Dict observation flattened, each runner stepping its arms as one native batched
env), on the default Cartesian-twist reach. Per layout: every runner samples S env
steps at once (its public ``sample``: the module's inference, the connectors and the
env), R rounds after a warm-up round; the env steps per second of wall time. Sampling
only, no learning: what the runners scale.

Beside each layout, the same number of plain processes (no Ray) stepping the same
batched env with uniform random actions for T seconds at once: the env's own rate
("bare env"), so that ``rllib / bare env`` is the share of the runner's time left to the
env (the rest is RLlib's: inference, connectors, episodes). Last, the host's ceiling:
bare ``mujoco.mj_step`` of the same one-arm world in one process and in two at once;
two runners cannot scale better than that on a shared machine. The figures go in
benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

import smoke  # benchmarks/smoke.py: --smoke

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples"))
import train_rllib  # noqa: E402  (examples/train_rllib.py: the configuration)


def sampling_rate(runners: int, arms: int, steps: int, repeats: int, seed: int) -> float:
    """Env steps per second (wall time) of every runner sampling ``steps`` env steps at
    once with the PPO module's exploration, after one warm-up round."""
    config = train_rllib.build_config(
        train_rllib.DEFAULT_ENV_ID, train_rllib.DEFAULT_ENV_KWARGS, runners, arms, seed, steps
    )
    algo = config.build_algo()

    def sample(runner) -> int:
        return sum(len(episode) for episode in runner.sample(num_timesteps=steps))

    try:
        group = algo.env_runner_group
        group.foreach_env_runner(sample, local_env_runner=False)  # warm-up
        start = time.perf_counter()
        total = 0
        for _ in range(repeats):
            total += sum(group.foreach_env_runner(sample, local_env_runner=False))
        return total / (time.perf_counter() - start)
    finally:
        algo.stop()


def _bare_env(arms: int, seconds: float, seed: int, ready, results) -> None:
    """One process: the default env's batched env of ``arms`` arms, uniform random
    actions, for ``seconds`` after every process is ready; env steps/s."""
    import gymnasium as gym
    import numpy as np

    import franka_sim_gym  # noqa: F401  (registers the ids)

    env = gym.make_vec(
        train_rllib.DEFAULT_ENV_ID,
        num_envs=arms,
        vectorization_mode="vector_entry_point",
        **train_rllib.DEFAULT_ENV_KWARGS,
    )
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    shape = env.action_space.shape
    env.step(rng.uniform(-1, 1, shape))  # warm-up
    ready.wait()
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        env.step(rng.uniform(-1, 1, shape))
        calls += 1
    results.put(calls * arms / (time.perf_counter() - start))


def _bare_mj_step(arms: int, seconds: float, seed: int, ready, results) -> None:
    """One process: cycles/s of ``arms`` one-arm worlds (mj_step on each arm's MjData)."""
    import mujoco

    from franka_sim_gym.sim.arm import ArmPhysics

    physics = ArmPhysics(n_arms=arms)
    model, datas = physics.model, physics.datas  # each arm's own one-arm world
    mujoco.mj_step(model, datas[0])
    ready.wait()
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(100):
            for data in datas:
                mujoco.mj_step(model, data)
        calls += 100
    results.put(calls / (time.perf_counter() - start))


def in_processes(target, processes: int, arms: int, seconds: float, seed: int) -> float:
    """The summed rate of ``processes`` fresh processes running ``target`` at once (they
    start timing together, once all have built their world)."""
    context = mp.get_context("spawn")
    ready = context.Barrier(processes)
    results = context.Queue()
    workers = [
        context.Process(target=target, args=(arms, seconds, seed + i, ready, results))
        for i in range(processes)
    ]
    for worker in workers:
        worker.start()
    total = sum(results.get(timeout=seconds + 300) for _ in workers)
    for worker in workers:
        worker.join()
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", type=int, default=8, help="N: arms per runner's batched env")
    parser.add_argument("--steps", type=int, default=1000, help="env steps per runner a round")
    parser.add_argument("--repeats", type=int, default=3, help="timed rounds")
    parser.add_argument("--seconds", type=float, default=5.0, help="bare env and mj_step time")
    parser.add_argument("--seed", type=int, default=0)
    args = smoke.parse_args(parser, steps=20, repeats=1, seconds=0.1)
    import ray

    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    train_rllib.start_local_ray()  # runners at this process's niceness
    layouts = [(1, 1), (2, 1), (1, args.arms), (2, args.arms)]
    rates, bare = {}, {}
    try:
        for runners, arms in layouts:
            rates[runners, arms] = sampling_rate(runners, arms, args.steps, args.repeats, args.seed)
            bare[runners, arms] = in_processes(_bare_env, runners, arms, args.seconds, args.seed)
            print(
                f"{runners} x {arms}: rllib {rates[runners, arms]:.0f}, "
                f"bare env {bare[runners, arms]:.0f} env steps/s",
                flush=True,
            )
    finally:
        ray.shutdown()
    mj = {p: in_processes(_bare_mj_step, p, 1, args.seconds, args.seed) for p in (1, 2)}
    base = rates[1, 1]
    print(f"ray {ray.__version__}, {os.cpu_count()} cores, load average {load} at the start")
    print(f"{args.repeats} rounds of {args.steps} env steps per runner, after a warm-up round")
    print(
        f"{'runners x arms':<16}{'rllib steps/s':>15}{'vs 1x1':>9}"
        f"{'bare env steps/s':>18}{'vs 1x1':>9}{'rllib / bare':>14}"
    )
    for layout, rate in rates.items():
        runners, arms = layout
        print(
            f"{f'{runners} x {arms}':<16}{rate:>15.0f}{rate / base:>9.2f}"
            f"{bare[layout]:>18.0f}{bare[layout] / bare[1, 1]:>9.2f}"
            f"{rate / bare[layout]:>14.2f}"
        )
    ceiling = mj[2] / mj[1]
    print(
        f"bare mj_step (one arm): 1 process {mj[1]:,.0f}/s, 2 processes {mj[2]:,.0f}/s "
        f"({ceiling:.2f}x): the host's ceiling for two runners"
    )
    print(
        "summary: "
        + " ".join(f"r{r}xa{a}={rate:.0f}" for (r, a), rate in rates.items())
        + f" two_runners_ratio={rates[2, 1] / base:.2f}"
        + f" bare_env_two_process_ratio={bare[2, 1] / bare[1, 1]:.2f}"
        + f" mj_step_two_process_ratio={ceiling:.2f}"
    )


if __name__ == "__main__":
    main()
