"""RLlib sampling throughput by runners x batched arms: 1x1, 2x1, 1xN, 2xN in one run.

    pip install 'franka-sim-gym[rllib]'
    python benchmarks/rllib_scaling.py [--arms N] [--steps S] [--repeats R]

examples/train_rllib.py's PPO configuration (the env named so that remote runners find
it, the Dict observation flattened, each runner stepping its arms as one native batched
env), on the default Cartesian-twist reach. Per layout: every runner samples S env
steps at once (its public ``sample``: the module's inference, the connectors and the
env), R rounds after a warm-up round; the env steps per second of wall time. Sampling
only, no learning: what the runners scale. Prints a table with each layout's ratio to
1x1; the figures go in benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", type=int, default=8, help="N: arms per runner's batched env")
    parser.add_argument("--steps", type=int, default=1000, help="env steps per runner a round")
    parser.add_argument("--repeats", type=int, default=3, help="timed rounds")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    import ray

    ray.init(include_dashboard=False, log_to_driver=False)
    layouts = [(1, 1), (2, 1), (1, args.arms), (2, args.arms)]
    rates = {}
    try:
        for runners, arms in layouts:
            rates[runners, arms] = sampling_rate(runners, arms, args.steps, args.repeats, args.seed)
            print(f"{runners} x {arms}: {rates[runners, arms]:.0f} env steps/s", flush=True)
    finally:
        ray.shutdown()
    base = rates[1, 1]
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"ray {ray.__version__}, {os.cpu_count()} cores, load average {load}")
    print(f"{args.repeats} rounds of {args.steps} env steps per runner, after a warm-up round")
    print(f"{'runners x arms':<16}{'env steps/s':>13}{'vs 1x1':>9}")
    for (runners, arms), rate in rates.items():
        print(f"{f'{runners} x {arms}':<16}{rate:>13.0f}{rate / base:>9.2f}")
    print(
        "summary: "
        + " ".join(f"r{r}xa{a}={rate:.0f}" for (r, a), rate in rates.items())
        + f" two_runners_ratio={rates[2, 1] / base:.2f}"
    )


if __name__ == "__main__":
    main()
