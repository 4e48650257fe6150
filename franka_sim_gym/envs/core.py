"""The batched core of every FrankaFCI env: n arms, each in its own MuJoCo world (sim/arm.py),
one controller call per cycle.

``FrankaFCIEnv`` is its n = 1 case; ``FrankaFCIVectorEnv`` and the SB3 adapter drive n
arms. One policy step is ``cycles_per_step`` cycles; per cycle the core stamps every
arm's command with the newest state's id (envs/commands.py computes all n commands in
one call), hands them to the channel models (one per arm) and runs one controller cycle
for all arms. The Python cost of a cycle is paid once, not once per arm, as long as every
arm's channel is perfect (the default); a lossy or delayed channel is consulted per arm.

Per-arm independence: a reflex on arm i freezes arm i's observation and info at the
cycle it happened (a single env stops there) while the others run on; a reset of arm i
touches only arm i. A reset teleports the arm, starts its motion (Move) and returns its
observation at once; the arm then sends nothing for its first ``SILENT_CYCLES`` cycles,
as libfranka reads states until the modes switch, and one more.

What the episode is about — goals, objects, observation extras, reward, success — is the
task's (envs/tasks/base.py), injected by name or instance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from gymnasium import spaces

from ..fci.config import ControllerConfig
from ..fci.controller import FciController
from ..fci.events import EventKind
from ..fci.wire import ROBOT_COMMAND_DTYPE
from ..reality import DrawBatch, RealityDraw, RealityProfile, draw, episode_seed, load_profile
from ..sim.arm import ArmPhysics
from ..sim.world import HOME_Q
from .channel import Channel, Links
from .commands import COMMAND_FIELD, MOVE, CommandGenerator, move_options
from .fci_reset import reset_through_fci
from .hands import EnvHands, hand_choice
from .infos import objects, step_info
from .observation import build_observation, observation_space
from .robot_settings import RobotSettings
from .tasks import Task, make_task

#: How an episode starts: "teleport" (the arm is placed at the start pose, errors and
#: frames cleared) or "fci" (as on a robot: recovery, then a joint motion there).
RESET_MODES = ("teleport", "fci")

#: libfranka reads states after Move until the modes switch, and one more, sending nothing.
SILENT_CYCLES = 2

__all__ = ["FciBatch", "draw_episode", "start_pose"]


def draw_episode(rng: np.random.Generator, noise: float, task: Task) -> tuple[np.ndarray, ...]:
    """An episode's start pose (``start_pose``) and its goal (``task.sample_goal``), drawn
    from ``rng`` in that order: what a reset draws, and what examples/deploy_pylibfranka.py
    draws for the same reaches."""
    return start_pose(rng, noise, task.home), task.sample_goal(rng)


def start_pose(
    rng: np.random.Generator, noise: float, home: np.ndarray | None = None
) -> np.ndarray:
    """``home`` (default: the robot's home pose) plus uniform noise of +-``noise`` rad per
    joint, drawn from ``rng``."""
    return (HOME_Q if home is None else home) + rng.uniform(-noise, noise, size=7)


def task_box(task: Task):
    """``safety_box="task"``: the task's workspace box (a ValueError if it has none)."""
    if task.safety_box is None:
        raise ValueError(f"safety_box='task': {type(task).__name__} declares no box")
    return task.safety_box


class FciBatch:
    """n episodes of a task on n simulated FR3s, stepped together (see the module
    docstring).

    The arguments are FrankaFCIEnv's (its docstring describes them); ``channel`` may
    also be a list with one model or spec per arm (a single ``Channel`` instance is
    copied per arm: every arm gets its own link and its own random stream). ``task`` is
    a name in ``tasks.TASKS`` (``task_kwargs`` are its arguments, e.g. Reach's
    ``reward_type`` and ``distance_threshold``) or a ``Task`` instance.
    """

    def __init__(
        self,
        n: int,
        action_interface: str = "joint_position",
        action_filter: str = "limit_rate",
        policy_hz: float = 25.0,
        max_episode_steps: int | None = None,
        task: str | Task = "reach",
        enforce_motion_limits: bool = True,
        enforce_comm_constraints: bool = True,
        channel: Channel | str | None | list = None,
        reset_noise: float = 0.05,
        robot: str = "fr3",
        gripper: bool | None = None,
        gripper_speed: float = 0.1,
        grasp_force: float = 20.0,
        configure_load: bool = True,
        cartesian_dof: int = 6,
        cartesian_limits: str | tuple[float, ...] = "conservative",
        safety_box=None,
        reset_mode: str = "teleport",
        scene: str | Path | None = None,
        controller_mode: str = "joint_impedance",
        joint_impedance=None,
        cartesian_impedance=None,
        collision_thresholds: tuple | None = None,
        reality: str | Path | dict | RealityProfile | None = None,
        **task_kwargs,
    ) -> None:
        if int(n) < 1:
            raise ValueError(f"the number of arms must be >= 1, got {n}")
        if reset_mode not in RESET_MODES:
            raise ValueError(f"unknown reset_mode {reset_mode!r}: expected one of {RESET_MODES}")
        if reset_mode == "fci" and int(n) != 1:
            # The move home takes hundreds of cycles of the whole world, which the other
            # arms' episodes would have to sit through: one arm per world (SyncVectorEnv).
            raise ValueError(
                f"reset_mode='fci' needs one arm per world, got {n}: use single envs "
                "(gym.make, or a SyncVectorEnv of them)"
            )
        self.reset_mode = reset_mode
        cycles = 1000.0 / policy_hz if policy_hz > 0 else 0.5
        if abs(cycles - round(cycles)) > 1e-9:
            raise ValueError(f"policy_hz={policy_hz}: 1000 / policy_hz must be a whole number")
        if action_interface not in MOVE:
            raise ValueError(
                f"unknown action_interface {action_interface!r}: expected one of {tuple(MOVE)}"
            )
        self.n = n = int(n)
        self.action_interface = action_interface
        self.cycles_per_step = int(round(cycles))
        self.task = make_task(task, **task_kwargs)
        if max_episode_steps is None:
            max_episode_steps = self.task.max_episode_steps
        if int(max_episode_steps) < 1:
            raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        self.max_episode_steps = int(max_episode_steps)
        self.reset_noise = float(reset_noise)
        if self.task.scene is not None and scene is not None:
            name = type(self.task).__name__
            raise ValueError(f"{name} has its own scene ({self.task.scene}): scene must be None")
        scene = self.task.scene if scene is None else scene
        #: the servo and the thresholds every episode starts with
        self.robot_settings = RobotSettings.from_arguments(
            action_interface,
            controller_mode,
            joint_impedance,
            cartesian_impedance,
            collision_thresholds,
        )
        self.config = ControllerConfig(
            robot=robot,
            enforce_motion_limits=enforce_motion_limits,
            enforce_comm_constraints=enforce_comm_constraints,
        )
        task = self.task
        #: the last action is the hand's width command
        self.gripper, mounted = hand_choice(type(task).__name__, task.hand, gripper)
        physics = ArmPhysics(n_arms=n, hand=mounted, scene=scene)
        #: the hands (None without one): envs/hands.py
        self.hands = None
        if mounted:
            self.hands = EnvHands(physics, task.hand, task.held_object, gripper_speed,
                                  grasp_force, configure_load)  # fmt: skip
        self.controller = FciController(physics, self.config)
        #: how the robot differs from its model, per episode (docs/reality.md)
        self.reality = load_profile(reality)
        #: each arm's draw of its episode (None: the ideal robot)
        self.draws: list[RealityDraw | None] = [None] * n
        self._draw_info = None
        self.links = Links(channel, n, drawn=not self.reality.link_is_ideal)
        self.links.robot_answers[...] = action_interface == "joint_position_async"
        #: each arm's channel model
        self.channels = self.links.channels
        self.commands = CommandGenerator(
            action_interface,
            action_filter,
            self.cycles_per_step,
            self.config.table,
            n=n,
            cartesian_dof=cartesian_dof,
            cartesian_limits=cartesian_limits,
            safety_box=task_box(self.task) if safety_box == "task" else safety_box,
        )
        self._dim = self.commands.action_dim
        #: the spaces of one arm
        self.action_space = spaces.Box(
            -1.0, 1.0, shape=(self._dim + 1 if self.gripper else self._dim,), dtype=np.float32
        )
        self.observation_space = observation_space(
            self.config.table, self.gripper, self.task.extra_space(), self.task.goal_dim
        )
        self._command = np.zeros(n, dtype=ROBOT_COMMAND_DTYPE)
        self._all = np.ones(n, dtype=bool)
        self._all.setflags(write=False)
        self.goals = np.zeros((n, self.task.goal_dim))
        self.steps = np.zeros(n, dtype=np.int64)
        self.cycles = np.zeros(n, dtype=np.int64)  # cycles of each arm's episode
        self._fresh = np.zeros(n, dtype=bool)  # reset, its silent cycles still to come

    # -- episodes ------------------------------------------------------------------------------

    def reset_arms(self, arms, rngs: list[np.random.Generator]) -> None:
        """Start new episodes on ``arms``, each drawing from its own ``rngs[i]`` (indexed by
        arm): teleport to the home pose plus seeded noise (or go there through the FCI:
        ``reset_mode="fci"``), Move; the task then places its objects and draws the goals
        (``draw_episode``'s order)."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        ctrl = self.controller
        noise = self.reset_noise
        home = self.task.home
        draws = None
        if not self.reality.is_ideal:
            # Seeded by the arm's random state, drawing nothing from it (reality/draw.py).
            draws = DrawBatch.stack(
                draw(self.reality, episode_seed(rngs[i])) for i in arms.tolist()
            )
            ctrl.apply_reality(arms, draws, scene=not self.reality.scene_is_ideal)
        q = np.stack([start_pose(rngs[i], noise, home) for i in arms.tolist()])
        if self.reset_mode == "fci":  # recovery and a joint motion home (one arm)
            reset_through_fci(ctrl, q[0])
        else:
            # A motion still running (a truncated episode) is stopped first, as a client
            # would: the teleport clears the joint references but not the Cartesian
            # generator's, whose twist (O_dP_EE_c) the next episode would start from.
            for i in np.flatnonzero(ctrl.in_motion[arms]).tolist():
                ctrl.stop_move(int(arms[i]))
            ids = ctrl.writer.message_id.copy()
            ctrl.reset(arms, q)
            # The reset publishes the teleported state under a new message id, for every
            # arm. The other arms' datagrams still in flight (a delayed channel) would then
            # look one cycle older than they are: keep the ids, so a reset of arm i never
            # touches arm j.
            ctrl.writer.message_id[...] = ids
            ctrl.states["message_id"] = ids
        controller, generator = MOVE[self.action_interface]
        controller = self.robot_settings.move_controller(controller)
        options = move_options(self.action_interface, ctrl.table, self.commands.scale)
        for i in arms.tolist():
            self.robot_settings.apply(ctrl, i)
            ctrl.move(i, int(controller), int(generator), **options)
        hands, physics = self.hands, ctrl.physics
        if hands is not None:
            hands.before_task_reset(arms, self.gripper, self.reset_mode == "teleport")
        self.goals[arms] = self.task.reset(arms, rngs, physics)
        if hands is not None:
            hands.after_task_reset(arms)
        if hands is not None or self.task.scene is not None:
            physics.forward(arms)  # the placed objects' frames
        if hands is not None:
            hands.configure_loads(ctrl, arms)
        self.commands.reset(arms)
        self.steps[arms] = 0
        self.cycles[arms] = 0
        self.links.reset(arms, rngs)
        if draws is not None:
            if self.links.drawn is not None:
                self.links.drawn.apply(arms, draws)
            for k, i in enumerate(arms.tolist()):
                self.draws[i] = draws.draws[k]
            self._draw_info = objects(self.draws)
        self._fresh[arms] = True

    def observe(self) -> tuple[dict, dict]:
        """Observations and infos of every arm as they stand (after a reset: lost 0)."""
        m = self._measured()
        zeros = np.zeros(self.n, dtype=np.int64)
        no_violations = np.zeros((self.n, self.controller.errors.shape[1]), dtype=bool)
        return self._observation(m), self._info(m, zeros, no_violations, np.zeros(self.n))

    # -- the step ------------------------------------------------------------------------------

    def check_actions(self, actions) -> np.ndarray:
        """(n, action dim) float64, or a ValueError naming what is wrong."""
        shape = (self.n, *self.action_space.shape)
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != shape:
            raise ValueError(f"actions must have shape {shape}, got {a.shape}")
        finite = np.isfinite(a).all(axis=1)
        if not finite.all():
            bad = np.flatnonzero(~finite).tolist()
            raise ValueError(f"actions must be finite: arm(s) {bad} got {a[bad].tolist()}")
        return a

    def step(self, actions: np.ndarray, active: np.ndarray | None = None):
        """One policy step of the ``active`` arms (default all) with (n, a) actions.

        Inactive arms send nothing (a running motion is stopped first) and their rows
        of the results are meaningless: they wait for a reset.

        Returns:
            obs (dict of (n, ...) arrays), reward (n,), terminated (n,), truncated (n,),
            info (dict of (n,) arrays, as Gymnasium's vector envs batch infos).
        """
        a = self.check_actions(actions)
        n, ctrl = self.n, self.controller
        active = self._all if active is None else np.asarray(active, dtype=bool)
        if not active.all():
            for i in np.flatnonzero(~active & ctrl.in_motion).tolist():
                ctrl.stop_move(i)
        if self.gripper:
            self.hands.command(a[:, self._dim], active)
            a = a[:, : self._dim]
        if self.hands is not None:
            self.hands.configure_loads(ctrl, np.flatnonzero(active))
        state = ctrl.states
        gen = self.commands
        gen.begin_step(a, state)
        self.links.begin_step(self.cycles_per_step)
        fresh = self._fresh & active
        self._fresh[active] = False
        frozen = np.zeros(n, dtype=bool)
        violations = np.zeros((n, ctrl.errors.shape[1]), dtype=bool)
        lost = np.zeros(n, dtype=np.int64)
        snapshot = None
        # Only the id and the active field change from cycle to cycle (the rest of the
        # command stays zero, as libfranka sends it).
        command = self._command
        command_id = command["message_id"]
        command_field = command[COMMAND_FIELD[self.action_interface]]
        published = state["message_id"]
        sending = active & ~fresh
        everyone = bool(sending.all())
        mask = self._all if everyone else sending
        # The cycle's calls, looked up once a step (a cycle is ~40 us: each look-up counts).
        command_for, receive, cycle_step = gen.command, ctrl.receive, ctrl.step
        perfect, transmit = self.links.perfect, self.links.transmit
        tick = self.hands.tick if self.gripper else None
        silent_until = SILENT_CYCLES if fresh.any() else -1  # (fresh is fixed for the step)
        k = -1
        for k in range(self.cycles_per_step):
            if k == silent_until:
                sending = active & ~frozen
                everyone = bool(sending.all())
                mask = self._all if everyone else sending
            command_id[...] = published
            command_field[...] = command_for(state, k, None if everyone else sending)
            if perfect:
                receive(command, mask)
            else:
                transmit(command, sending, lost, receive)
            if tick is not None:
                tick(active & ~frozen)
            events = cycle_step()
            if events:
                ended = [
                    e.robot
                    for e in events
                    if e.kind is EventKind.MOVE_FINISHED and active[e.robot] and not frozen[e.robot]
                ]
                if ended:
                    # A single env stops at the cycle its motion ended: keep that cycle's
                    # observation and info for these arms while the others run on.
                    snapshot = self._freeze(ended, k, frozen, active, violations, snapshot)
                    sending = active & ~frozen & (~fresh if k + 1 < SILENT_CYCLES else True)
                    everyone = bool(sending.all())
                    mask = self._all if everyone else sending
                    if not (active & ~frozen).any():
                        break
        running = active & ~frozen
        self.cycles[running] += k + 1
        violations[running] |= ctrl.violations.take()[running]
        self.steps[active] += 1
        m = self._measured(frozen, snapshot)
        obs = self._observation(m)
        task = self.task
        terminated = frozen
        penalty = np.zeros(n)
        if frozen.any():
            # A reflex must never be a shortcut to a higher return: charge the worst
            # reward for every step the episode would still have had. The charge rides in
            # the info, and the step's reward is compute_reward of that info: HER's
            # relabelling charges it the same way (a relabelled terminal step would
            # otherwise look like a free success).
            remaining = self.max_episode_steps - self.steps[frozen]
            penalty[frozen] = task.worst_step_reward * (remaining + 1)
        reward = task.compute_reward(
            obs["achieved_goal"], obs["desired_goal"], {"reflex_penalty": penalty}
        ).astype(np.float64)
        truncated = active & ~terminated & (self.steps >= self.max_episode_steps)
        return obs, reward, terminated, truncated, self._info(m, lost, violations, penalty)

    # -- internals -----------------------------------------------------------------------------

    def _freeze(self, ended, k, frozen, active, violations, snapshot):
        ctrl = self.controller
        running = active & ~frozen
        violations[running] |= ctrl.violations.take()[running]
        frozen[ended] = True
        self.cycles[ended] += k + 1
        now = self._measured()
        if snapshot is None:
            snapshot = {key: value.copy() for key, value in now.items() if value is not None}
        for key, value in snapshot.items():
            value[ended] = now[key][ended]
        return snapshot

    def _measured(self, frozen=None, snapshot=None) -> dict:
        """Every arm's state, EE position (float64), hand width, achieved goal and the
        task's extras; the rows of ``frozen`` arms from the snapshot of their last cycle."""
        ctrl = self.controller
        ee = ctrl.writer.O_T_EE[:, 12:15].copy()
        achieved, extra = self.task.observe(ctrl.physics, ee)
        m = {
            "states": ctrl.states,
            "ee": ee,
            "width": self.hands.width() if self.gripper else None,
            "achieved": achieved,
            "extra": extra,
        }
        if snapshot is not None:
            for key, value in snapshot.items():
                m[key] = np.where(frozen.reshape(-1, *[1] * (value.ndim - 1)), value, m[key])
        return m

    def _observation(self, m: dict) -> dict[str, np.ndarray]:
        states = m["states"]
        return build_observation(
            self.observation_space,
            states["q"],
            states["dq"],
            m["ee"],
            self.goals,
            states["O_dP_EE_c"],
            m["width"],
            achieved=m["achieved"],
            extra=m["extra"],
        )

    def _info(self, m, lost, violations, penalty) -> dict[str, np.ndarray]:
        is_success = np.asarray(self.task.is_success(m["achieved"], self.goals), dtype=bool)
        info = step_info(
            m["states"], lost, self.links.longest_lost, violations, self.cycles, is_success, penalty
        )
        if self._draw_info is not None:
            # Every arm's draw (reality/draw.py RealityDraw: immutable, copied for free).
            info["reality"] = self._draw_info.copy()
        return info
