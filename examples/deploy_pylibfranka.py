"""Run a reach policy trained by examples/train_sb3.py through pylibfranka's active control loop.

    franka-sim-gym serve &                                   # or a real FR3's address
    python examples/deploy_pylibfranka.py --host 127.0.0.1 --model runs/reach/model.zip

The same script a user points at a real FR3. Per reach: a joint motion to the
start pose (the env's home pose plus its seeded reset noise), then the policy in
pylibfranka's ``readOnce()`` / ``writeOnce()`` loop at 1 kHz: one action every
``1000 / policy_hz`` cycles, turned into one command per cycle by the env's own
``CommandGenerator`` (envs/commands.py: interpolation, libfranka's low-pass filter
and rate limiter), from observations built by the env's own ``build_observation``
(envs/observation.py). Goals are drawn by the env's reach task. A reflex is
recovered with AutomaticErrorRecovery. Ends with one line
``deploy: success_rate=<x> reflexes=<n> link_success_rate=<y>``.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable

import numpy as np
import pylibfranka as fr

from franka_sim_gym.envs.commands import CommandGenerator
from franka_sim_gym.envs.observation import build_observation, observation_space
from franka_sim_gym.envs.tasks.reach import Reach
from franka_sim_gym.fci.tables import FER, FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE
from franka_sim_gym.sim.world import HOME_Q

#: The state fields the command generator reads (libfranka's ControlLoop reads the same).
_REFERENCE_FIELDS = ("q_d", "dq_d", "ddq_d", "tau_J_d")
#: Cycles at the start of a motion before the success-rate window (100 cycles) is full.
_WINDOW = 100


def _start(robot, interface: str):
    """Start the motion of ``interface``; returns the control and its command type."""
    impedance = fr.ControllerMode.JointImpedance
    if interface == "joint_position":
        return robot.start_joint_position_control(impedance), fr.JointPositions
    if interface == "joint_velocity":
        return robot.start_joint_velocity_control(impedance), fr.JointVelocities
    if interface == "torque":
        return robot.start_torque_control(), fr.Torques
    raise ValueError(f"unknown action_interface {interface!r}")


def move_home(robot, target: np.ndarray) -> None:
    """A cosine-blended joint motion to ``target``, slow enough for every joint limit
    (peak 0.5 rad/s); the env's reset teleports there, a real arm has to move."""
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    t, q0, duration = 0.0, None, 1.0
    while True:
        state, period = control.readOnce()
        t += period.to_sec()
        if q0 is None:
            q0 = np.array(state.q_d)
            duration = max(1.0, math.pi / 2 * float(np.max(np.abs(target - q0))) / 0.5)
        s = 0.5 * (1.0 - math.cos(math.pi * min(t / duration, 1.0)))
        command = fr.JointPositions((q0 + s * (target - q0)).tolist())
        if t >= duration + 0.2:  # a little time to settle
            command.motion_finished = True
            control.writeOnce(command)
            return
        control.writeOnce(command)


class Reacher:
    """One reach through pylibfranka, with the env's command generation and observations.

    Args:
        policy: anything with SB3's ``predict(obs, deterministic=True) -> (action, state)``.
        env_kwargs: the env arguments the policy was trained with (interface, filter, rate).
    """

    def __init__(self, policy, env_kwargs: dict) -> None:
        self.policy = policy
        self.interface = env_kwargs.get("action_interface", "joint_position")
        policy_hz = float(env_kwargs.get("policy_hz", 25.0))
        self.cycles_per_step = int(round(1000.0 / policy_hz))
        self.max_steps = int(env_kwargs.get("max_episode_steps", 50))
        table = FER if env_kwargs.get("robot", "fr3") == "fer" else FR3
        self.commands = CommandGenerator(
            self.interface,
            env_kwargs.get("action_filter", "limit_rate"),
            self.cycles_per_step,
            table,
        )
        self.space = observation_space(table)
        self.task = Reach(
            reward_type=env_kwargs.get("reward_type", "sparse"),
            distance_threshold=float(env_kwargs.get("distance_threshold", 0.05)),
        )
        self._state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)

    def observe(self, state, goal: np.ndarray) -> dict:
        """The env's observation of a pylibfranka RobotState."""
        obs = build_observation(
            self.space,
            np.array(state.q)[None],
            np.array(state.dq)[None],
            np.array(state.O_T_EE)[None, 12:15],
            goal[None],
        )
        return {key: value[0] for key, value in obs.items()}

    def reach(self, robot, goal: np.ndarray, rates: list[float]) -> bool:
        """Run one episode towards ``goal``; True when the end pose is within the radius.

        ControlException (a reflex) propagates to the caller.
        """
        control, command_type = _start(robot, self.interface)
        gen, mirror = self.commands, self._state
        gen.reset()
        last_step, last_cycle = self.max_steps - 1, self.cycles_per_step - 1
        cycle = 0
        for step in range(self.max_steps):
            for k in range(self.cycles_per_step):
                state, _ = control.readOnce()
                for name in _REFERENCE_FIELDS:
                    mirror[name][0] = getattr(state, name)
                if k == 0:
                    action, _ = self.policy.predict(self.observe(state, goal), deterministic=True)
                    gen.begin_step(np.asarray(action, dtype=np.float64)[None, :7], mirror)
                command = command_type(gen.command(mirror, k)[0].tolist())
                if cycle >= _WINDOW:
                    rates.append(state.control_command_success_rate)
                cycle += 1
                if step == last_step and k == last_cycle:
                    command.motion_finished = True
                control.writeOnce(command)
        final = robot.read_once()
        ee = np.array(final.O_T_EE)[12:15]
        return bool(self.task.is_success(ee, goal))


def deploy(
    host: str,
    policy,
    episodes: int = 10,
    seed: int = 0,
    env_kwargs: dict | None = None,
    log: Callable[[str], None] = print,
) -> dict:
    """``episodes`` reaches on the robot at ``host``; success, reflexes and the link's rate."""
    env_kwargs = dict(env_kwargs or {})
    reacher = Reacher(policy, env_kwargs)
    noise = float(env_kwargs.get("reset_noise", 0.05))
    rng = np.random.default_rng(seed)
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    successes, reflexes, rates = 0, 0, []
    for episode in range(episodes):
        # Drawn as the env's reset draws them: the start pose's noise, then the goal.
        start = HOME_Q + rng.uniform(-noise, noise, size=7)
        goal = reacher.task.sample_goal(rng)
        move_home(robot, start)
        try:
            success = reacher.reach(robot, goal, rates)
        except fr.ControlException as exc:  # a reflex: the robot aborted the motion
            reflexes += 1
            success = False
            log(f"reach {episode}: reflex: {exc}")
            robot.automatic_error_recovery()
        successes += success
        log(f"reach {episode}: goal {np.round(goal, 3).tolist()} success={success}")
    link = float(np.mean(rates)) if rates else float("nan")
    return {
        "success_rate": successes / episodes,
        "reflexes": reflexes,
        "link_success_rate": link,
        "link_min_success_rate": float(np.min(rates)) if rates else float("nan"),
    }


def load_policy(path: str, algo: str, env_kwargs: dict):
    """An SB3 model saved by train_sb3.py (HER-trained models load with an env for spaces)."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import PPO, SAC, TD3

    import franka_sim_gym  # noqa: F401  (registers the ids)

    torch.set_num_threads(1)  # inference inside the 1 kHz loop: no thread pool wake-ups
    env = gym.make("FrankaFCI-v0", **env_kwargs)
    return {"sac": SAC, "td3": TD3, "ppo": PPO}[algo].load(path, env=env)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1", help="robot (or simulator) address")
    parser.add_argument("--model", required=True, help="model.zip written by train_sb3.py")
    parser.add_argument("--algo", default="sac", choices=("sac", "td3", "ppo"))
    parser.add_argument("--episodes", type=int, default=10, help="reaches")
    parser.add_argument("--seed", type=int, default=0, help="start poses and goals")
    parser.add_argument("--env-kwargs", default="{}", help="as given to train_sb3.py (JSON)")
    args = parser.parse_args()
    env_kwargs = json.loads(args.env_kwargs)
    policy = load_policy(args.model, args.algo, env_kwargs)
    result = deploy(args.host, policy, args.episodes, args.seed, env_kwargs)
    print(f"link: min control_command_success_rate {result['link_min_success_rate']:.3f}")
    print(
        f"deploy: success_rate={result['success_rate']:.3f} reflexes={result['reflexes']} "
        f"link_success_rate={result['link_success_rate']:.3f}"
    )


if __name__ == "__main__":
    main()
