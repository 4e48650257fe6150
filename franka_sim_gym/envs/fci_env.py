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

from ..sim.render import OffscreenRenderer
from .core import FciBatch, info_row


class FrankaFCIEnv(gym.Env):
    """Reach with a simulated FR3 under the rules its FCI enforces.

    Args:
        action_interface: "joint_position" (default), "joint_velocity",
            "cartesian_pose", "cartesian_velocity" or "torque".
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
        gripper: mount the Franka Hand (its mass is then in the arm's dynamics, and the
            EE frame, O_T_EE and the achieved goal are its TCP, as F_T_NE reports) and add
            an eighth action, the commanded opening width (-1 closed … 1 open, 0.08 m),
            applied through the same hand model as the gripper server (the fingers move
            at ``gripper_speed``); the observation gains the measured width.
        gripper_speed: finger speed of the width command [m/s] (default 0.1).
        cartesian_dof: the Cartesian interfaces' action length: 6 (default: translation,
            then a base-frame rotation vector) or 3 (translation only; the orientation
            is held where the motion started).
        cartesian_limits: the targets of the Cartesian rate limiter ("limit_rate"):
            "conservative" (default: what the robot's joint-side checks accept) or
            "libfranka" (libfranka's own constants, which trip errors 29 / 30 as on
            the robot), or six numbers (m/s, m/s^2, m/s^3, rad/s, rad/s^2, rad/s^3).
        reset_mode: "teleport" (default: the arm is placed at the start pose; errors,
            reflex_reason and the configured frames are cleared) or "fci" (a reset a
            real robot could do: StopMove, AutomaticErrorRecovery after a reflex, then
            a joint-position motion to the start pose, judged by the robot's checks;
            frames are kept). Single envs only (the vector env teleports).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 25}

    def __init__(
        self,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        **kwargs,
    ) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            modes = self.metadata["render_modes"]
            raise ValueError(f"render_mode {render_mode!r}: expected None or one of {modes}")
        self.width, self.height = int(width), int(height)
        self._renderer = None
        self._viewer = None
        self.render_mode = render_mode
        #: the batched core with one arm: the vector env runs the same code with n arms
        # Every other knob (and its default) is the batched core's: one list of them for
        # the single and the vector env; an unknown one is a TypeError naming it.
        self.core = FciBatch(1, **kwargs)
        core = self.core
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

    # -- Gymnasium API -----------------------------------------------------------------------

    @property
    def reset_noise(self) -> float:
        """Half-width [rad] of the uniform noise on each joint of the home pose at reset."""
        return self.core.reset_noise

    @reset_noise.setter
    def reset_noise(self, value: float) -> None:
        self.core.reset_noise = float(value)

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
        obs, reward, terminated, truncated, info = self.core.step(action[None, :])
        done = bool(terminated[0]), bool(truncated[0])
        return _row(obs), float(reward[0]), *done, info_row(info, 0)

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
                physics.base_pos[0] + self.core.goals[0],
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


def _row(obs: dict) -> dict:
    return {key: value[0] for key, value in obs.items()}
