"""FrankaFCI-v0: a Gymnasium env whose robot is the simulated FCI controller, in-process.

One env step is ``1000 / policy_hz`` cycles of the controller. Between policy
steps the env plays the libfranka client (envs/commands.py): it turns the
action into one command per cycle, stamps it with the id of the newest state,
and hands it to the channel model (envs/channel.py), which decides what
reaches the robot. The env never checks a robot limit itself: an episode ends
because the controller raised a reflex, and ``info`` names it.

Copies (``copy.deepcopy``, ``pickle``) are rebuilt, not cloned: a new env made with the
same arguments replays the episode so far — its reset from the random state it started
from, then its actions — and so continues bit for bit as the original would, because an
episode is a function of its seed and actions (the copy tests of
tests/envs/test_env_gymnasium.py). MuJoCo's data and the C kernels are never copied:
numpy views and kernels bound to one MjData's memory could not follow a copy.
"""

from __future__ import annotations

import copy
import inspect
import os
import sys
import warnings

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium.envs.registration import EnvSpec

from ..sim.render import OffscreenRenderer
from .core import FciBatch
from .infos import info_row


class FrankaFCIEnv(gym.Env):
    """A task (Reach by default) on a simulated FR3 under the rules its FCI enforces.

    Actions are ``Box(-1, 1)``; values outside it are clipped to it, component by
    component (docs/env.md, "Actions"); NaN, infinite or wrongly shaped ones are a
    ValueError.

    Args:
        task: "reach" (default; envs/tasks/TASKS) or a ``Task`` instance; the task's
            own arguments are keywords of the env too (Reach: ``reward_type``,
            ``distance_threshold``).
        action_interface: "joint_position" (default), "joint_velocity",
            "cartesian_pose", "cartesian_velocity" or "torque".
        action_filter: how the action becomes per-cycle commands: "limit_rate"
            (default: libfranka's low-pass + rate limiter), "lowpass",
            "interpolate", "interpolate_limit_rate" (the interpolation, then the
            low-pass and rate limiter: docs/env.md) or "none" (the target held: a naive
            client).
        policy_hz: policy rate; 1000 / policy_hz cycles per step (default 25 Hz,
            40 cycles).
        max_episode_steps: steps before truncation, and the length the reflex charge
            counts (default: ``gym.make``'s ``max_episode_steps``, i.e. the TimeLimit
            wrapper's, else the task's: Reach 50 steps, i.e. 2 s at 25 Hz).
        reward_type: "sparse" (default) or "dense".
        distance_threshold: success radius [m] (default 0.05).
        enforce_motion_limits, enforce_comm_constraints: the robot's switches
            (default on: a violation aborts the motion and ends the episode).
        channel: None (a perfect link), a ``Channel``, or a spec such as
            "loss:0.01", "bursty", "delay:2".
        reset_noise: half-width [rad] of the uniform noise added to each joint of
            the home pose at reset (default 0.05).
        robot: "fr3" (default) or "fer" limit tables.
        render_mode: None, "rgb_array" (MuJoCo offscreen: EGL unless MUJOCO_GL says
            otherwise) or "human" (MuJoCo's viewer; needs a display: without one a
            RuntimeError says so when the env is made).
        width, height: the rgb_array frame size [px].
        gripper: mount the Franka Hand (default: the task's choice; Reach: off; its mass
            is then in the arm's dynamics, and the EE frame, O_T_EE and the achieved goal
            are its TCP, as F_T_NE reports) and add an eighth action, the commanded
            opening width (-1 closed … 1 open, 0.08 m), on the same force-limited
            finger servo as the gripper server's physics hand (the fingers move at
            ``gripper_speed``); the observation gains the measured width.
        gripper_speed: finger speed of the width command [m/s] (default 0.1).
        grasp_force: the fingers' force limit when they close [N] (default 20): a
            closing width command is a grasp, and fingers stopped by an object squeeze
            it with this force (the gripper server's grasp rule, sim/finger_drive.py);
            also the squeeze of tasks that hold the fingers shut (Push, PegInsertion).
        configure_load: while the hand holds the task's object (both fingertips on it),
            configure its mass as the robot's load (SetLoad), so the external-force
            estimate does not read its weight (default True); False leaves the load
            unconfigured: the weight then reads as an external force, as on a robot
            nobody told.
        cartesian_dof: the Cartesian interfaces' action length: 6 (default: translation,
            then a base-frame rotation vector) or 3 (translation only; the orientation
            is held where the motion started).
        cartesian_limits: the targets of the Cartesian rate limiter ("limit_rate"):
            "conservative" (default: what the robot's joint-side checks accept) or
            "libfranka" (libfranka's own constants, which trip errors 29 / 30 as on
            the robot), or six numbers (m/s, m/s^2, m/s^3, rad/s, rad/s^2, rad/s^3).
        safety_box: the client's workspace box for the TCP (Cartesian interfaces): None
            (default: none), ``"task"`` (the task's ``safety_box``: Push,
            PickAndPlace, PegInsertion declare one) or two corners ``[[x, y, z], [x, y,
            z]]`` in the base frame [m]. The commanded translational velocity toward
            each wall is bounded so the TCP brakes to a stop at it, before the rate
            limiter (envs/commands.py; docs/env.md "The safety box").
        reset_mode: "teleport" (default: the arm is placed at the start pose; errors,
            reflex_reason and the configured frames are cleared) or "fci" (a reset a
            real robot could do: StopMove, AutomaticErrorRecovery after a reflex, then
            a joint-position motion to the start pose, judged by the robot's checks;
            frames are kept). Single envs only (the vector env teleports).
        scene: a scene fragment on the table, one copy per arm: a shipped name
            ("block", "peg_in_hole") or an MJCF file (default: the bare table; a task
            with objects brings its own).
        controller_mode: the robot's internal servo under the motion generators:
            "joint_impedance" (default) or "cartesian_impedance" (a spring on the
            stiffness frame K: docs/robot-state.md); the torque interface is its own.
        joint_impedance: SetJointImpedance's stiffness [Nm/rad], 7 values or one (default:
            the robot's, 3000, 3000, 3000, 2500, 2500, 2000, 2000), set at every reset.
        cartesian_impedance: SetCartesianImpedance's K_x (x, y, z N/m in 10 ... 3000;
            roll, pitch, yaw Nm/rad in 1 ... 300), set at every reset (default 3000 /
            300).
        collision_thresholds: SetCollisionBehavior in libfranka's 4-argument form,
            ``(lower_torque, upper_torque, lower_force, upper_force)`` (Nm, N; 7, 7, 6
            and 6 values or scalars), set at every reset (default: the robot's,
            fci/contact/collision.py). A force above an upper threshold is a collision reflex
            (``joint_reflex`` / ``cartesian_reflex``) that ends the episode.
        reality: how the robot differs from its own model and from ideal sensors, per
            episode (docs/reality.md): "ideal" (default: no difference), "fr3" (one
            nominal imperfect FR3: its model's mass error, joint friction, sensor noise
            at the datasheet's levels), "randomized" (a robot drawn around fr3 every
            episode, its scene and its link too), a mapping or a JSON file's path. The
            episode's draw is ``info["reality"]`` (a ``RealityDraw``), seeded by the
            env's random state at reset without drawing from it.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 25}

    def __init__(
        self,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        max_episode_steps: int | None = None,
        **kwargs,
    ) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            modes = self.metadata["render_modes"]
            raise ValueError(f"render_mode {render_mode!r}: expected None or one of {modes}")
        if render_mode == "human":
            check_display()
        self.width, self.height = int(width), int(height)
        self._renderer = None
        self._viewer = None
        self.render_mode = render_mode
        if max_episode_steps is None:
            max_episode_steps = length_from_make()
        # What a copy is rebuilt from (the arguments as given: a Channel instance is
        # used, and so changed, by the env).
        self._arguments = copy.deepcopy(
            {"render_mode": render_mode, "width": width, "height": height, **kwargs}
        )
        #: the episodes a copy replays: [random state at reset, reset_noise, actions]
        self._history: list[list] = []
        #: the batched core with one arm: the vector env runs the same code with n arms
        # Every other knob (and its default) is the batched core's: one list of them for
        # the single and the vector env; an unknown one is a TypeError naming it.
        self.core = FciBatch(1, max_episode_steps=max_episode_steps, **kwargs)
        core = self.core
        self._arguments["max_episode_steps"] = core.max_episode_steps
        self.controller = core.controller
        self.config = core.config
        self.task = core.task
        self.commands = core.commands
        self.channel = core.channels[0]
        self.action_interface = core.action_interface
        self.cycles_per_step = core.cycles_per_step
        self.max_episode_steps = core.max_episode_steps
        self.gripper = core.gripper
        self.action_space = core.action_space
        self.observation_space = core.observation_space
        # One frame per policy step plays in real time (RecordVideo reads render_fps).
        self.metadata = {**self.metadata, "render_fps": round(1000 / self.cycles_per_step)}

    # -- Gymnasium API -----------------------------------------------------------------------

    @property
    def reset_noise(self) -> float:
        """Half-width [rad] of the uniform noise on each joint of the home pose at reset."""
        return self.core.reset_noise

    @reset_noise.setter
    def reset_noise(self, value: float) -> None:
        self.core.reset_noise = float(value)
        self._arguments["reset_noise"] = float(value)

    @property
    def cycles(self) -> int:
        """Cycles of this episode (info["cycles"])."""
        return int(self.core.cycles[0])

    @property
    def hand(self):
        """The Franka Hand model (None without ``gripper``)."""
        return self.core.hands[0] if self.gripper else None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Go to the home pose plus seeded noise (teleported, or through the FCI with
        ``reset_mode="fci"``), start the motion, draw a goal."""
        super().reset(seed=seed)
        episode = [copy.deepcopy(self.np_random.bit_generator.state), self.reset_noise, []]
        if self.core.reset_mode == "teleport":
            # A teleport starts from nothing of the previous episode (tested): a copy
            # replays this one alone; an FCI reset starts where the last one stopped.
            self._history.clear()
        self._history.append(episode)
        self.core.reset_arms([0], [self.np_random])
        obs, info = self.core.observe()
        return _row(obs), info_row(info, 0)

    def step(self, action):
        action = np.asarray(action, dtype=np.float64)
        if action.shape != self.action_space.shape:
            shape = self.action_space.shape
            raise ValueError(f"action must have shape {shape}, got {action.shape}")
        if not np.all(np.isfinite(action)):
            raise ValueError(f"action must be finite, got {action}")
        if self._history:
            self._history[-1][2].append(action.copy())
        obs, reward, terminated, truncated, info = self.core.step(action[None, :])
        done = bool(terminated[0]), bool(truncated[0])
        return _row(obs), float(reward[0]), *done, info_row(info, 0)

    def render(self):
        """An RGB frame (rgb_array) of the arm and the goal, or a viewer sync (human)."""
        physics = self.controller.physics
        if self.render_mode == "human":
            if self._viewer is None:
                check_display()
                from mujoco import viewer

                self._viewer = viewer.launch_passive(physics.model, physics.data)
            self._viewer.sync()
            return None
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = OffscreenRenderer(physics.model, self.width, self.height)
            camera = self._renderer.camera
            camera.lookat[:] = (0.35, 0.0, 0.4)
            camera.distance, camera.azimuth, camera.elevation = 1.6, 135, -20
        renderer = self._renderer
        renderer.update_scene(physics.data)
        scene = renderer.scene
        radius = getattr(self.task, "distance_threshold", 0.02)
        if scene.ngeom < scene.maxgeom:  # the goal: a translucent red sphere
            mujoco.mjv_initGeom(
                scene.geoms[scene.ngeom],
                mujoco.mjtGeom.mjGEOM_SPHERE,
                np.array([radius, 0, 0]),
                self.core.goals[0].astype(np.float64),
                np.eye(3).ravel(),
                np.array([1.0, 0.1, 0.1, 0.6], dtype=np.float32),
            )
            scene.ngeom += 1
        return renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def compute_reward(self, achieved_goal, desired_goal, info):
        """Vectorised reward (SB3's HER relabels goals with it)."""
        return self.task.compute_reward(achieved_goal, desired_goal, info)

    # -- copies ------------------------------------------------------------------------------

    def __deepcopy__(self, memo: dict) -> FrankaFCIEnv:
        return replayed(self._arguments, self._history, self._random_state(), self.spec)

    def __reduce__(self):
        """Pickled as its arguments and its episode so far (replayed when loaded)."""
        return replayed, (self._arguments, self._history, self._random_state(), self.spec)

    def _random_state(self):
        if self._np_random_seed is None:  # never reset nor drawn from
            return None
        return copy.deepcopy(self.np_random.bit_generator.state), self.np_random_seed


def replayed(arguments: dict, history: list, random_state, spec: EnvSpec | None):
    """A FrankaFCIEnv made with ``arguments`` that replays ``history`` (its episodes'
    resets and actions) and ends with the random state ``random_state``: the state of the
    env these were taken from, bit for bit."""
    env = FrankaFCIEnv(**copy.deepcopy(arguments))
    env.spec = spec
    for state, noise, actions in history:
        env.reset_noise = noise
        env.np_random = np.random.Generator(np.random.PCG64())
        env.np_random.bit_generator.state = state
        env._history.append([copy.deepcopy(state), noise, []])
        env.core.reset_arms([0], [env.np_random])
        for action in actions:
            env.step(action)
    env.reset_noise = arguments.get("reset_noise", env.reset_noise)
    if random_state is not None:
        state, seed = random_state
        if not history:
            env.np_random = np.random.Generator(np.random.PCG64())
        env.np_random.bit_generator.state = state  # in place: the channel shares it
        env._np_random_seed = seed  # gym.Env's; np_random's setter would say -1
    return env


def length_from_make() -> int | None:
    """The episode length in force for an env being made by ``gym.make``: its
    ``max_episode_steps`` argument, else the registered spec's; None (the task's
    length) for an env made otherwise.

    Gymnasium hands that length to the TimeLimit wrapper alone (the env it creates gets
    a spec without it), but the env needs it: a reflex is charged the worst reward for
    every step the episode would still have had. So the env reads it from the arguments
    of the ``gym.make`` call that is creating it.
    """
    frame = inspect.currentframe()
    while frame is not None and frame.f_code is not gym.make.__code__:
        frame = frame.f_back
    if frame is None:
        return None
    arguments = inspect.getargvalues(frame).locals
    length = arguments.get("max_episode_steps")
    if length is None or length == -1:  # -1: no TimeLimit; the registered length stays
        spec = arguments.get("id")
        spec = spec if isinstance(spec, EnvSpec) else gym.spec(spec)
        length = spec.max_episode_steps
    return None if length is None else int(length)


def check_display() -> None:
    """Raise a RuntimeError saying what to do when MuJoCo's viewer cannot open a window
    (GLFW would print an error and end the process instead)."""
    advice = (
        "render_mode='human' needs a display, and GLFW cannot open one here ({}). "
        "Headless, use render_mode='rgb_array' (offscreen EGL), e.g. with "
        "gymnasium.wrappers.RecordVideo, or examples/record_video.py."
    )
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise RuntimeError(advice.format("DISPLAY and WAYLAND_DISPLAY are unset"))
    import glfw  # MuJoCo's viewer's window library (a dependency of mujoco)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if not glfw.init():
            reasons = "; ".join(str(w.message) for w in caught) or "glfw.init() failed"
            raise RuntimeError(advice.format(reasons))


def _row(obs: dict) -> dict:
    return {key: value[0] for key, value in obs.items()}
