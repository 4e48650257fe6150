"""What a reality profile costs: env steps/s under each profile against the ideal robot.

    python benchmarks/reality_rate.py [--seconds S] [--actions smooth|random] [--id ID]

Rows: the single env and the batched env (N = 16, 64), each under ``ideal``, ``fr3`` and
``randomized`` (all checks on, resets counted), with the ratio to bare mj_step of as many
bare one-arm worlds (no scene) and to ideal, and how many episodes ended (terminated or
truncated) under each.

The profiles of a row are built once and stepped in turn, one env step each, every step
timed in this process's CPU time and summed per profile, for ``--seconds`` per row: a
shared host's speed drifts over seconds, and each profile sees the same drift. The
actions are the same for every profile: ``smooth`` (default) a slow sine per arm and
axis at a tenth of the action box, a policy's kind of stream, so that each profile runs
the same episodes and its figure is its cost; ``random`` uniform over the box, whose
episodes end in reflexes near the stops, where one profile's draw and another's part
ways, so that the figure mixes a cost with different resets.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import smoke  # benchmarks/smoke.py: --smoke

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics

clock = time.process_time
PROFILES = ("ideal", "fr3", "randomized")
#: the smooth actions: period [env steps] and amplitude (of the action box's half-width):
#: a stream that trips nothing under any profile (its episodes end at their time limit)
PERIOD, AMPLITUDE = 100, 0.1


def make(env_id: str, n: int | None, profile: str):
    """The env (or n-arm batched env) under ``profile``, reset with seed 0."""
    if n is None:
        env = gym.make(env_id, reality=profile)
    else:
        env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                           reality=profile)  # fmt: skip
    env.reset(seed=0)
    return env


class Actions:
    """The same action sequence for every profile of a row."""

    def __init__(self, kind: str, space) -> None:
        self.kind = kind
        self.low, self.high = space.low.astype(np.float64), space.high.astype(np.float64)
        self.rng = np.random.default_rng(0)
        # A phase per arm and axis: the arms of a batch move apart.
        self.phase = np.random.default_rng(1).uniform(0, 2 * np.pi, size=space.shape)

    def at(self, t: int) -> np.ndarray:
        if self.kind == "random":
            x = self.rng.uniform(-1, 1, size=self.low.shape)
        else:
            x = AMPLITUDE * np.sin(2 * np.pi * t / PERIOD + self.phase)
        middle, half = (self.high + self.low) / 2, (self.high - self.low) / 2
        return (middle + half * x).astype(np.float32)


def measure(env_id: str, n: int | None, seconds: float, kind: str) -> dict[str, tuple]:
    """{profile: (env steps/s, episodes ended)} over ``seconds`` of interleaved steps."""
    envs = {p: make(env_id, n, p) for p in PROFILES}
    actions = Actions(kind, envs["ideal"].action_space)
    spent = dict.fromkeys(PROFILES, 0.0)
    ended = dict.fromkeys(PROFILES, 0)
    t, end = 0, clock() + seconds
    while clock() < end:
        action = actions.at(t)
        for p, env in envs.items():
            start = clock()
            _, _, terminated, truncated, _ = env.step(action)
            done = np.logical_or(terminated, truncated)
            if n is None and done:
                env.reset()
            spent[p] += clock() - start
            ended[p] += int(np.count_nonzero(done))
        t += 1
    for env in envs.values():
        env.close()
    return {p: (t / spent[p], ended[p]) for p in PROFILES}


def bare_arm_cycles(n: int, seconds: float) -> float:
    """Arm-cycles/s of mj_step on n one-arm worlds in turn."""
    import mujoco

    physics = ArmPhysics(n_arms=n)
    calls, start = 0, clock()
    while clock() - start < seconds:
        for data in physics.datas:
            mujoco.mj_step(physics.model, data)
        calls += 1
    return calls * n / (clock() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="interleaved measuring per row (default 30)")  # fmt: skip
    parser.add_argument("--actions", choices=("smooth", "random"), default="smooth")
    parser.add_argument("--id", default="FrankaFCI-v0", help="env id (default FrankaFCI-v0)")
    args = smoke.parse_args(parser, seconds=0.5)
    cycles = gym.spec(args.id).kwargs.get("policy_hz", 25)
    cycles = round(1000 / cycles)
    print(describe())
    print(f"{args.id}, {cycles} cycles a step; {args.actions} actions; "
          f"{args.seconds:g} s of interleaved steps a row")  # fmt: skip
    print(f"{'row':<22}{'profile':<12}{'steps/s':>10}{'arm-cycles/s':>14}"
          f"{'vs mj_step':>12}{'vs ideal':>10}{'ended':>8}")  # fmt: skip
    for n in (None, 16, 64):
        bare = bare_arm_cycles(n or 1, min(args.seconds, 2.0))
        figures = measure(args.id, n, args.seconds, args.actions)
        row = "single env" if n is None else f"batched, N={n}"
        ideal = figures["ideal"][0]
        for profile, (rate, ended) in figures.items():
            rate *= n or 1  # arm-steps
            print(
                f"{row:<22}{profile:<12}{rate:>10,.0f}{rate * cycles:>14,.0f}"
                f"{rate * cycles / bare:>12.3f}{rate / (ideal * (n or 1)):>10.3f}{ended:>8}"
            )


if __name__ == "__main__":
    main()
