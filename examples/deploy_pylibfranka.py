"""Run a reach policy trained by examples/train_sb3.py through pylibfranka's active control loop.

    franka-sim-gym serve &                                   # or a real FR3's address
    python examples/deploy_pylibfranka.py --host 127.0.0.1 --model runs/reach/model.zip

The same script a user points at a real FR3, for policies of every action interface:
joint position, joint velocity, Cartesian pose (O_T_EE_c, 16 values, column-major),
Cartesian velocity (O_dP_EE_c, 6 values; both with 3 or 6 dof) and torque. The
algorithm, env id and env arguments come from ``train_config.json`` next to the model
(written by train_sb3.py); ``--algo``, ``--env-id`` and ``--env-kwargs`` override them
(``--env-kwargs`` replaces the training arguments, as in evaluate.py). Without the file
the defaults are SAC on FrankaFCI-v0 with the arguments given.

Per reach: a joint motion to the start pose (the env's home pose plus its seeded reset
noise), then the policy in pylibfranka's ``readOnce()`` / ``writeOnce()`` loop at 1 kHz,
under the controller mode the env uses (joint impedance for every motion generator,
Cartesian ones included; torque control for torques): one action every
``1000 / policy_hz`` cycles, turned into one command per cycle by the env's own
``CommandGenerator`` (envs/commands.py: interpolation, libfranka's low-pass filter and
rate limiter, joint or Cartesian, against the robot's references q_d, dq_d, ddq_d,
tau_J_d, O_T_EE_c, O_dP_EE_c, O_ddP_EE_c copied from the RobotState), from
observations built by the env's own ``build_observation`` (envs/observation.py).
A velocity motion is then brought to rest (a zero target through the same filters, at
most 1 s) before it is finished: a motion finished while it still moves can end in a
reflex (libfranka: "Motion finished commanded, but the robot is still moving!").
Position, pose and torque motions finish with the last step's last command (held on a
fixed target, the low-pass filter and rate limiter can keep ringing). Goals are drawn
by the env's reach task. A reflex is recovered with AutomaticErrorRecovery. Ends with
one line ``deploy: success_rate=<x> reflexes=<n> link_success_rate=<y>``.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pylibfranka as fr
from evaluate import DEFAULT_ALGO, DEFAULT_ENV_ID, load_model  # examples/evaluate.py

from franka_sim_gym.envs.commands import CARTESIAN, CommandGenerator
from franka_sim_gym.envs.core import draw_episode, task_box
from franka_sim_gym.envs.observation import build_observation, observation_space
from franka_sim_gym.envs.tasks.reach import Reach
from franka_sim_gym.fci.tables import FER, FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE

#: The state fields the command generator reads (libfranka's ControlLoop reads the same):
#: the joint references, and the Cartesian ones of the Cartesian interfaces.
_REFERENCE_FIELDS = ("q_d", "dq_d", "ddq_d", "tau_J_d", "O_T_EE_c", "O_dP_EE_c", "O_ddP_EE_c")
#: ... and what the safety box of a twist reads (envs/commands.py)
_BOX_FIELDS = ("O_T_EE",)
#: Cycles at the start of a motion before the success-rate window (100 cycles) is full.
_WINDOW = 100
#: The velocity interfaces, whose motions are brought to rest before they are finished.
_VELOCITY = ("joint_velocity", "cartesian_velocity")
#: The longest wait for a velocity motion to come to rest after the last step [cycles].
_SETTLE_CYCLES = 1000
#: At rest: the reference's velocity (rad/s; m/s and rad/s) and its rate below these.
_REST_VELOCITY, _REST_ACCELERATION = 1e-3, 5e-2


def _start(robot, interface: str):
    """Start the motion of ``interface``; returns the control and its command type.

    The controller modes are the env's (envs/commands.py MOVE): joint impedance under every
    motion generator (Robot::control's default), torques under the external controller.
    """
    impedance = fr.ControllerMode.JointImpedance
    if interface == "joint_position":
        return robot.start_joint_position_control(impedance), fr.JointPositions
    if interface == "joint_velocity":
        return robot.start_joint_velocity_control(impedance), fr.JointVelocities
    if interface == "cartesian_pose":
        return robot.start_cartesian_pose_control(impedance), fr.CartesianPose
    if interface == "cartesian_velocity":
        return robot.start_cartesian_velocity_control(impedance), fr.CartesianVelocities
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


class NumpyActor:
    """A trained SAC or TD3 actor's deterministic action, computed in numpy.

    SB3's ``predict`` costs ~0.15 ms warm but close to 1 ms in a 1 kHz loop (its Python
    and torch dispatch run cold once every 100 cycles), which makes the cycle that
    carries the policy step miss the robot's deadline. The same network in numpy
    (the dict observation flattened in the extractor's key order, the actor's linear
    layers and activations, the tanh squash and the action space's unscaling) takes a
    few tens of microseconds. :meth:`of` checks it against ``predict`` and falls back
    to the model itself where it does not apply (PPO, gSDE) or does not agree.
    """

    def __init__(self, keys: list[str], layers: list, low: np.ndarray, high: np.ndarray):
        self.keys, self.layers, self.low, self.high = keys, layers, low, high

    @classmethod
    def of(cls, model, samples: int = 8):
        """The numpy actor of ``model``, or ``model`` when it has no such actor. A model
        behind observation normalisation (train_sb3.py's default) keeps it: the numpy
        actor of the model behind the same statistics."""
        import torch.nn as nn

        from franka_sim_gym.training.sb3_zoo import NormalizedPolicy

        if isinstance(model, NormalizedPolicy):
            return NormalizedPolicy(cls.of(model.model, samples), model.normalization)
        actor = getattr(model.policy, "actor", None)
        extractor = getattr(actor, "features_extractor", None)
        if actor is None or getattr(actor, "use_sde", False) or extractor is None:
            return model
        modules = (
            list(actor.latent_pi) + [actor.mu, nn.Tanh()]
            if hasattr(actor, "latent_pi")
            else list(actor.mu)
        )
        layers = []
        for module in modules:
            if isinstance(module, nn.Linear):
                weight = module.weight.detach().cpu().numpy().T.copy()
                layers.append(("linear", weight, module.bias.detach().cpu().numpy().copy()))
            elif isinstance(module, nn.ReLU | nn.Tanh):
                layers.append(("relu" if isinstance(module, nn.ReLU) else "tanh", None, None))
            elif not isinstance(module, nn.Identity):
                return model
        space = model.action_space
        numpy_actor = cls(list(extractor.extractors.keys()), layers, space.low, space.high)
        for _ in range(samples):
            obs = model.observation_space.sample()
            expected, _ = model.predict(obs, deterministic=True)
            got, _ = numpy_actor.predict(obs)
            if not np.allclose(got, expected, atol=1e-5):
                return model
        return numpy_actor

    def predict(self, obs: dict, deterministic: bool = True):
        """(action, None), as SB3's ``predict`` of one observation."""
        x = np.concatenate(
            [np.asarray(obs[key], dtype=np.float32).reshape(-1) for key in self.keys]
        )
        for kind, weight, bias in self.layers:
            if kind == "linear":
                x = x @ weight + bias
            elif kind == "relu":
                x = np.maximum(x, 0.0)
            else:
                x = np.tanh(x)
        return self.low + 0.5 * (x + 1.0) * (self.high - self.low), None


class Reacher:
    """One reach through pylibfranka, with the env's command generation and observations.

    Args:
        policy: anything with SB3's ``predict(obs, deterministic=True) -> (action, state)``.
        env_kwargs: the env arguments the policy was trained with (interface, filter, rate,
            Cartesian dof and limits), the registered id's defaults included
            (:func:`env_settings`).
    """

    def __init__(self, policy, env_kwargs: dict) -> None:
        if env_kwargs.get("gripper", False):
            raise ValueError("deploy drives the arm only: policies trained with gripper=True")
        self.policy = policy
        self.interface = env_kwargs.get("action_interface", "joint_position")
        policy_hz = float(env_kwargs.get("policy_hz", 25.0))
        self.cycles_per_step = int(round(1000.0 / policy_hz))
        self.max_steps = int(env_kwargs.get("max_episode_steps", 50))
        table = FER if env_kwargs.get("robot", "fr3") == "fer" else FR3
        limits = env_kwargs.get("cartesian_limits", "conservative")
        self.task = Reach(
            reward_type=env_kwargs.get("reward_type", "sparse"),
            distance_threshold=float(env_kwargs.get("distance_threshold", 0.05)),
        )
        box = env_kwargs.get("safety_box")
        self.commands = CommandGenerator(
            self.interface,
            env_kwargs.get("action_filter", "limit_rate"),
            self.cycles_per_step,
            table,
            cartesian_dof=int(env_kwargs.get("cartesian_dof", 6)),
            # JSON gives six numbers as a list
            cartesian_limits=limits if isinstance(limits, str) else tuple(limits),
            # the client's workspace box, as the env's client keeps it
            safety_box=task_box(self.task) if box == "task" else box,
        )
        self.space = observation_space(table)
        self._state = np.zeros(1, dtype=ROBOT_STATE_DTYPE)
        #: the last reach's distance to its goal [m]: at its last step, and at rest
        self.last_distances = (math.nan, math.nan)

    def observe(self, state, goal: np.ndarray) -> dict:
        """The env's observation of a pylibfranka RobotState."""
        obs = build_observation(
            self.space,
            np.array(state.q)[None],
            np.array(state.dq)[None],
            np.array(state.O_T_EE)[None, 12:15],
            goal[None],
            np.array(state.O_dP_EE_c)[None],
        )
        return {key: value[0] for key, value in obs.items()}

    def _mirror(self, state) -> np.ndarray:
        """The generator's view of ``state``: its references in the env's state array."""
        mirror = self._state
        for name in _REFERENCE_FIELDS:
            mirror[name][0] = getattr(state, name)
        if self.commands.safety_box is not None:
            for name in _BOX_FIELDS:
                mirror[name][0] = getattr(state, name)
        return mirror

    def _at_rest(self, state) -> bool:
        """The commanded velocity has come to rest (the reference's velocity and its rate)."""
        if self.interface in CARTESIAN:
            velocity, acceleration = state.O_dP_EE_c, state.O_ddP_EE_c
        else:
            velocity, acceleration = state.dq_d, state.ddq_d
        return (
            float(np.max(np.abs(velocity))) < _REST_VELOCITY
            and float(np.max(np.abs(acceleration))) < _REST_ACCELERATION
        )

    def reach(self, robot, goal: np.ndarray, rates: list[float]) -> bool:
        """Run one episode towards ``goal``; True when the end pose is within the radius.

        ControlException (a reflex) propagates to the caller.
        """
        self.last_distances = (math.nan, math.nan)
        control, command_type = _start(robot, self.interface)
        gen = self.commands
        gen.reset()
        # Velocity motions are stopped after the last step (_stop); the others finish with it.
        stop = self.interface in _VELOCITY
        last_step, last_cycle = self.max_steps - 1, self.cycles_per_step - 1
        cycle = 0
        for step in range(self.max_steps):
            for k in range(self.cycles_per_step):
                state, _ = control.readOnce()
                mirror = self._mirror(state)
                if k == 0:
                    action, _ = self.policy.predict(self.observe(state, goal), deterministic=True)
                    action = np.asarray(action, dtype=np.float64).reshape(-1)
                    gen.begin_step(action[None, : gen.action_dim], mirror)
                command = command_type(gen.command(mirror, k)[0].tolist())
                if cycle >= _WINDOW:
                    rates.append(state.control_command_success_rate)
                cycle += 1
                if step == last_step and k == last_cycle and not stop:
                    command.motion_finished = True
                control.writeOnce(command)
        # Judged where the env judges is_success: the state of the last step's last cycle.
        at_end = np.array(state.O_T_EE)[12:15]
        if stop:
            self._stop(control, command_type, rates, cycle)
        at_rest = np.array(robot.read_once().O_T_EE)[12:15]
        self.last_distances = (
            float(np.linalg.norm(at_end - goal)),
            float(np.linalg.norm(at_rest - goal)),
        )
        return bool(self.task.is_success(at_end, goal))

    def _stop(self, control, command_type, rates: list[float], cycle: int) -> None:
        """Bring a velocity motion to rest through the same filters (a zero target: what a
        unit action of 0 asks), then finish it; at most ``_SETTLE_CYCLES`` cycles."""
        gen = self.commands
        last = gen.cycles_per_step - 1
        for k in range(_SETTLE_CYCLES + 1):
            state, _ = control.readOnce()
            mirror = self._mirror(state)
            if k == 0:
                gen.begin_step(np.zeros((1, gen.action_dim)), mirror)
            if cycle + k >= _WINDOW:
                rates.append(state.control_command_success_rate)
            command = command_type(gen.command(mirror, min(k, last))[0].tolist())
            if k == _SETTLE_CYCLES or self._at_rest(state):
                command.motion_finished = True
                control.writeOnce(command)
                return
            control.writeOnce(command)


def deploy(
    host: str,
    policy,
    episodes: int = 10,
    seed: int = 0,
    env_kwargs: dict | None = None,
    log: Callable[[str], None] = print,
) -> dict:
    """``episodes`` reaches on the robot at ``host``; success, reflexes and the link's rate.

    ``env_kwargs`` are the env's arguments including the registered id's own
    (:func:`env_settings`): e.g. ``{"action_interface": "cartesian_velocity"}`` for a
    policy trained on FrankaFCICartesianVelocity-v0.
    """
    env_kwargs = dict(env_kwargs or {})
    reacher = Reacher(policy, env_kwargs)
    noise = float(env_kwargs.get("reset_noise", 0.05))
    rng = np.random.default_rng(seed)
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    successes, reflexes, rates = 0, 0, []
    for episode in range(episodes):
        start, goal = draw_episode(rng, noise, reacher.task)  # as the env's reset draws them
        move_home(robot, start)
        try:
            success = reacher.reach(robot, goal, rates)
        except fr.ControlException as exc:  # a reflex: the robot aborted the motion
            reflexes += 1
            success = False
            log(f"reach {episode}: reflex: {exc}")
            robot.automatic_error_recovery()
        successes += success
        end, rest = reacher.last_distances
        log(
            f"reach {episode}: goal {np.round(goal, 3).tolist()} success={success} "
            f"(distance {end * 100:.1f} cm at the last step, {rest * 100:.1f} cm at rest)"
        )
    link = float(np.mean(rates)) if rates else float("nan")
    return {
        "success_rate": successes / episodes,
        "reflexes": reflexes,
        "link_success_rate": link,
        "link_min_success_rate": float(np.min(rates)) if rates else float("nan"),
    }


def in_process(policy, env_id: str, env_kwargs: dict, episodes: int = 10, seed: int = 0) -> float:
    """The success rate of the same reaches in the env, in-process: the starts and goals
    :func:`deploy` draws (one generator, ``envs.core.draw_episode`` reach after reach),
    the same policy, success judged at the episode's last step. What the deployed rate
    is to be compared with. (A lossy channel model also draws from that generator while
    it runs: with one, the later reaches' starts and goals differ from deploy's.)"""
    import gymnasium as gym

    import franka_sim_gym  # noqa: F401  (registers the ids)

    core = gym.make(env_id, **env_kwargs).unwrapped.core
    rng = np.random.default_rng(seed)
    successes = 0
    for _ in range(episodes):
        core.reset_arms([0], [rng])
        obs, info = core.observe()
        for _ in range(core.max_episode_steps):
            action, _ = policy.predict({k: v[0] for k, v in obs.items()}, deterministic=True)
            obs, _, terminated, truncated, info = core.step(np.asarray(action, float)[None])
            if terminated[0] or truncated[0]:
                break
        successes += bool(info["is_success"][0])
    return successes / episodes


def env_settings(env_id: str, env_kwargs: dict) -> dict:
    """The arguments an env of ``env_id`` made with ``env_kwargs`` runs with: the
    registered id's own (e.g. its action_interface) under the explicit ones."""
    import gymnasium as gym

    import franka_sim_gym  # noqa: F401  (registers the ids)

    return {**gym.spec(env_id).kwargs, **env_kwargs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1", help="robot (or simulator) address")
    parser.add_argument("--model", required=True, help="model.zip written by train_sb3.py")
    parser.add_argument(
        "--algo",
        default=None,
        choices=("sac", "td3", "ppo"),
        help=f"default: train_config.json's, else {DEFAULT_ALGO}",
    )
    parser.add_argument("--episodes", type=int, default=10, help="reaches")
    parser.add_argument("--seed", type=int, default=0, help="start poses and goals")
    parser.add_argument(
        "--env-id", default=None, help=f"default: train_config.json's, else {DEFAULT_ENV_ID}"
    )
    parser.add_argument(
        "--env-kwargs",
        default=None,
        help="JSON, as given to train_sb3.py; default: train_config.json's, else {}",
    )
    args = parser.parse_args()
    kwargs = json.loads(args.env_kwargs) if args.env_kwargs is not None else None
    model, config = load_model(Path(args.model), args.algo, args.env_id, kwargs)
    policy = NumpyActor.of(model)
    env_id, env_kwargs = config["env_id"], config["env_kwargs"]
    print(f"policy: {config['algo']} on {env_id} {env_kwargs}")
    settings = env_settings(env_id, env_kwargs)
    result = deploy(args.host, policy, args.episodes, args.seed, settings)
    print(f"link: min control_command_success_rate {result['link_min_success_rate']:.3f}")
    reference = in_process(policy, env_id, env_kwargs, args.episodes, args.seed)
    print(f"in-process: success_rate={reference:.3f} (the env, the same starts and goals)")
    print(
        f"deploy: success_rate={result['success_rate']:.3f} reflexes={result['reflexes']} "
        f"link_success_rate={result['link_success_rate']:.3f}"
    )


if __name__ == "__main__":
    main()
