"""RLlib sampling throughput by runners x batched arms: 1x1, 2x1, 1xN, 2xN in one run.

    pip install 'franka-sim-gym[rllib]'
    python benchmarks/rllib_scaling.py [--arms N] [--iterations K] [--batch-size B]

examples/train_rllib.py's PPO configuration (the env named so that remote runners find
it, the Dict observation flattened, each runner stepping its arms as one native batched
env), on the default Cartesian-twist reach. Per layout: K training iterations of B env
steps; the env steps sampled per second of RLlib's sampling timer (all runners in
parallel, wall time), over the iterations after the first (its time includes the
runners' start). Prints a table with each layout's ratio to 1x1; the figures of the
whole run go in benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples"))
import train_rllib  # noqa: E402  (examples/train_rllib.py: the configuration)


def sampling_rate(runners: int, arms: int, iterations: int, batch_size: int, seed: int) -> float:
    """Env steps sampled per second of sampling, iterations 2..K."""
    config = train_rllib.build_config(
        train_rllib.DEFAULT_ENV_ID,
        train_rllib.DEFAULT_ENV_KWARGS,
        runners,
        arms,
        seed,
        batch_size,
    )
    algo = config.build_algo()
    steps = seconds = 0.0
    try:
        for iteration in range(iterations):
            result = algo.train()
            if iteration == 0 and iterations > 1:
                continue
            steps += float(result["env_runners"]["num_env_steps_sampled"])
            seconds += float(result["timers"]["env_runner_sampling_timer"])
    finally:
        algo.stop()
    return steps / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", type=int, default=8, help="N: arms per runner's batched env")
    parser.add_argument("--iterations", type=int, default=4)
    parser.add_argument("--batch-size", type=int, default=2000, help="env steps per iteration")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    import ray

    ray.init(include_dashboard=False, log_to_driver=False)
    layouts = [(1, 1), (2, 1), (1, args.arms), (2, args.arms)]
    rates = {}
    try:
        for runners, arms in layouts:
            rates[runners, arms] = sampling_rate(
                runners, arms, args.iterations, args.batch_size, args.seed
            )
            print(f"{runners} x {arms}: {rates[runners, arms]:.0f} env steps/s", flush=True)
    finally:
        ray.shutdown()
    base = rates[1, 1]
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"ray {ray.__version__}, {os.cpu_count()} cores, load average {load}")
    print(f"{args.iterations} iterations of {args.batch_size} env steps, the first left out")
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
