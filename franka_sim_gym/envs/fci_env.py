"""FrankaFCI-v0: a Gymnasium env whose robot is the simulated FCI controller, in-process.

One env step is ``1000 / policy_hz`` cycles of the controller. Between policy
steps the env plays the libfranka client (envs/commands.py): it turns the
action into one command per cycle, stamps it with the id of the newest state,
and hands it to the channel model (envs/channel.py), which decides what
reaches the robot. The env never checks a robot limit itself: an episode ends
because the controller raised a reflex, and ``info`` names it.
"""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from ..fci.config import ControllerConfig
from ..fci.controller import FciController
from ..fci.errors import error_names
from ..fci.events import EventKind
from ..fci.wire import (
    ROBOT_COMMAND_DTYPE,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
)
from ..sim.arm import ArmPhysics
from ..sim.gripper import MAX_WIDTH, FrankaHand
from ..sim.render import OffscreenRenderer
from ..sim.world import HOME_Q
from .channel import Channel, make_channel
from .commands import CommandGenerator
from .tasks.reach import Reach

_MOVE = {
    "joint_position": (MoveControllerMode.kJointImpedance, MoveMotionGeneratorMode.kJointPosition),
    "joint_velocity": (MoveControllerMode.kJointImpedance, MoveMotionGeneratorMode.kJointVelocity),
    "torque": (MoveControllerMode.kExternalController, MoveMotionGeneratorMode.kNone),
}
_FIELD = {"joint_position": "q_c", "joint_velocity": "dq_c", "torque": "tau_J_d"}


class FrankaFCIEnv(gym.Env):
    """Reach with a simulated FR3 under the rules its FCI enforces.

    Args:
        action_interface: "joint_position" (default), "joint_velocity" or "torque".
            (The Cartesian interfaces arrive with the Cartesian generators.)
        action_filter: how the action becomes per-cycle commands: "limit_rate"
            (default: libfranka's low-pass + rate limiter), "lowpass",
            "interpolate" or "none" (the target held: a naive client).
        policy_hz: policy rate; 1000 / policy_hz cycles per step (default 25 Hz,
            40 cycles).
        max_episode_steps: steps before truncation (default 50, i.e. 2 s at 25 Hz).
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
            otherwise) or "human" (MuJoCo's viewer; needs a display).
        width, height: the rgb_array frame size [px].
        gripper: mount the Franka Hand (its mass is then in the arm's dynamics) and add
            an eighth action, the commanded opening width (-1 closed … 1 open, 0.08 m),
            applied through the same hand model as the gripper server (the fingers move
            at ``gripper_speed``); the observation gains the measured width.
        gripper_speed: finger speed of the width command [m/s] (default 0.1).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 25}

    def __init__(
        self,
        action_interface: str = "joint_position",
        action_filter: str = "limit_rate",
        policy_hz: float = 25.0,
        max_episode_steps: int = 50,
        reward_type: str = "sparse",
        distance_threshold: float = 0.05,
        enforce_motion_limits: bool = True,
        enforce_comm_constraints: bool = True,
        channel: Channel | str | None = None,
        reset_noise: float = 0.05,
        robot: str = "fr3",
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        gripper: bool = False,
        gripper_speed: float = 0.1,
    ) -> None:
        cycles = 1000.0 / policy_hz
        if policy_hz <= 0 or abs(cycles - round(cycles)) > 1e-9:
            raise ValueError(f"policy_hz={policy_hz}: 1000 / policy_hz must be a whole number")
        if action_interface not in _MOVE:
            raise ValueError(
                f"unknown action_interface {action_interface!r}: expected one of {tuple(_MOVE)}"
            )
        if render_mode not in (None, *self.metadata["render_modes"]):
            modes = self.metadata["render_modes"]
            raise ValueError(f"render_mode {render_mode!r}: expected None or one of {modes}")
        self.width, self.height = int(width), int(height)
        self._renderer = None
        self._viewer = None
        self.action_interface = action_interface
        self.cycles_per_step = int(round(cycles))
        self.max_episode_steps = int(max_episode_steps)
        self.reset_noise = float(reset_noise)
        self.render_mode = render_mode
        self.task = Reach(reward_type=reward_type, distance_threshold=distance_threshold)
        self.config = ControllerConfig(
            robot=robot,
            enforce_motion_limits=enforce_motion_limits,
            enforce_comm_constraints=enforce_comm_constraints,
        )
        self.gripper = bool(gripper)
        self.gripper_speed = float(gripper_speed)
        self.hand = FrankaHand() if self.gripper else None
        self.controller = FciController(ArmPhysics(n_arms=1, hand=self.gripper), self.config)
        self.channel = make_channel(channel)
        self.commands = CommandGenerator(
            action_interface, action_filter, self.cycles_per_step, self.config.table
        )
        table = self.config.table
        self.action_space = spaces.Box(
            -1.0, 1.0, shape=(8 if self.gripper else 7,), dtype=np.float32
        )
        q_lo = (table.q_lower - 0.2).astype(np.float32)
        q_hi = (table.q_upper + 0.2).astype(np.float32)
        dq_hi = np.full(7, 20.0, dtype=np.float32)  # measured speed is bounded by physics
        box = np.full(3, 2.0, dtype=np.float32)  # the FR3 reaches ~0.9 m; EE frames may add
        width = (
            [np.zeros(1, np.float32), np.full(1, MAX_WIDTH, np.float32)] if gripper else [[], []]
        )
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(
                    np.concatenate([q_lo, -dq_hi, -box, width[0]]).astype(np.float32),
                    np.concatenate([q_hi, dq_hi, box, width[1]]).astype(np.float32),
                    dtype=np.float32,
                ),
                "achieved_goal": spaces.Box(-box, box, dtype=np.float32),
                "desired_goal": spaces.Box(-box, box, dtype=np.float32),
            }
        )
        self._command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
        self._mask = np.ones(1, dtype=bool)
        self._goal = np.zeros(3)
        self._steps = 0
        self._lost_run = 0
        self._longest_lost = 0
        self.cycles = 0

    # -- Gymnasium API -----------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Teleport to the home pose plus seeded noise, start the motion, draw a goal."""
        super().reset(seed=seed)
        rng = self.np_random
        self.cycles = 0  # cycles of this episode (info["cycles"])
        q = HOME_Q + rng.uniform(-self.reset_noise, self.reset_noise, size=7)
        ctrl = self.controller
        ctrl.reset(0, q)
        ctrl.violations.take()
        if self.gripper:
            self.hand = FrankaHand()  # open (the physics fingers were reset open too)
        self.channel.reset(rng)
        self.commands.reset()
        controller_mode, generator = _MOVE[self.action_interface]
        ctrl.move(0, int(controller_mode), int(generator))
        # libfranka reads states until the modes switch, and one more, sending nothing.
        for _ in range(2):
            ctrl.step()
            self.cycles += 1
        self._goal = self.task.sample_goal(rng)
        self._steps = 0
        self._lost_run = 0
        self._longest_lost = 0
        return self._observation(), self._info(lost=0, violations=())

    def step(self, action):
        action = np.asarray(action, dtype=np.float64).reshape(self.action_space.shape)
        if not np.all(np.isfinite(action)):
            raise ValueError(f"action must be finite, got {action}")
        if self.gripper:
            target = (np.clip(action[7], -1.0, 1.0) + 1.0) / 2.0 * MAX_WIDTH
            if abs(target - self.hand.width) > 1e-6:
                self.hand.move(target, self.gripper_speed)
            action = action[:7]
        ctrl = self.controller
        state = ctrl.states
        self.commands.begin_step(action[None, :], state)
        field = _FIELD[self.action_interface]
        lost = 0
        aborted = False
        # Only the id and the active field change from cycle to cycle (the rest of the
        # command stays zero, as libfranka sends it).
        command = self._command
        command_id, command_field = command["message_id"], command[field]
        for k in range(self.cycles_per_step):
            open_cycle = state["message_id"][0]
            command_id[0] = open_cycle
            command_field[0] = self.commands.command(state, k)[0]
            answered = False
            for delivered in self.channel.transmit(command):
                answered |= bool(delivered["message_id"][0] == open_cycle)
                ctrl.receive(delivered, self._mask)
            # A cycle is lost when no command answering it reached the robot in time.
            lost += not answered
            self._lost_run = 0 if answered else self._lost_run + 1
            self._longest_lost = max(self._longest_lost, self._lost_run)
            if self.gripper:
                self.hand.step(1e-3)
                ctrl.physics.set_finger_width(0, self.hand.width)
            events = ctrl.step()
            self.cycles += 1
            if any(e.kind is EventKind.MOVE_FINISHED for e in events):
                aborted = True
                break
        self._steps += 1
        violations = error_names(ctrl.violations.take()[0])
        obs = self._observation()
        info = self._info(lost=lost, violations=violations)
        reward = float(self.task.compute_reward(obs["achieved_goal"], obs["desired_goal"]))
        terminated = aborted
        if aborted:
            # A reflex must never be a shortcut to a higher return: charge the worst
            # reward for every step the episode would still have had.
            remaining = self.max_episode_steps - self._steps
            reward += self.task.worst_step_reward * (remaining + 1)
        truncated = (not terminated) and self._steps >= self.max_episode_steps
        return obs, reward, terminated, truncated, info

    def render(self):
        """An RGB frame (rgb_array) of the arm and the goal, or a viewer sync (human)."""
        physics = self.controller.physics
        if self.render_mode == "human":
            if self._viewer is None:
                from mujoco import viewer

                self._viewer = viewer.launch_passive(physics.model, physics.data)
            self._viewer.sync()
            return None
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = OffscreenRenderer(physics.model, self.width, self.height)
            camera = self._renderer.camera
            camera.lookat[:] = physics.base_pos[0] + (0.35, 0.0, 0.4)
            camera.distance, camera.azimuth, camera.elevation = 1.6, 135, -20
        renderer = self._renderer
        renderer.update_scene(physics.data)
        scene = renderer.scene
        if scene.ngeom < scene.maxgeom:  # the goal: a translucent red sphere
            mujoco.mjv_initGeom(
                scene.geoms[scene.ngeom],
                mujoco.mjtGeom.mjGEOM_SPHERE,
                np.array([self.task.distance_threshold, 0, 0]),
                physics.base_pos[0] + self._goal,
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

    # -- internals -----------------------------------------------------------------------------

    def _ee_position(self) -> np.ndarray:
        return self.controller.writer.O_T_EE[0, 12:15].copy()

    def _observation(self) -> dict:
        s = self.controller.states[0]
        ee = self._ee_position()
        parts = [s["q"], s["dq"], ee]
        if self.gripper:
            parts.append(self.controller.physics.finger_width()[:1])
        obs = np.concatenate(parts).astype(np.float32)
        space = self.observation_space["observation"]
        np.clip(obs, space.low, space.high, out=obs)  # the bounds are the bounds
        return {
            "observation": obs,
            "achieved_goal": np.clip(ee, -2.0, 2.0).astype(np.float32),
            "desired_goal": self._goal.astype(np.float32),
        }

    def _info(self, lost: int, violations: tuple[str, ...]) -> dict:
        ctrl = self.controller
        s = ctrl.states[0]
        ee = self._ee_position()
        return {
            "errors": error_names(s["errors"]),
            "reflex_reason": error_names(s["reflex_reason"]),
            "robot_mode": RobotMode(int(s["robot_mode"])).name,
            "control_command_success_rate": float(s["control_command_success_rate"]),
            "lost_cycles": lost,
            "longest_lost_run": self._longest_lost,
            "violations": violations,
            "cycles": self.cycles,
            "is_success": bool(self.task.is_success(ee, self._goal)),
        }
