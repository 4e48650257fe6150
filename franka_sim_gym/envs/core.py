"""The batched core of every FrankaFCI env: n arms in one MuJoCo world, one controller call
per cycle.

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
"""

from __future__ import annotations

import copy

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
from ..sim.world import HOME_Q
from .channel import Channel, make_channel
from .commands import CommandGenerator
from .fci_reset import reset_through_fci
from .observation import build_observation, observation_space
from .tasks.reach import Reach

#: How an episode starts: "teleport" (the arm is placed at the start pose, errors and
#: frames cleared) or "fci" (as on a robot: recovery, then a joint motion there).
RESET_MODES = ("teleport", "fci")

MOVE = {
    "joint_position": (MoveControllerMode.kJointImpedance, MoveMotionGeneratorMode.kJointPosition),
    "joint_velocity": (MoveControllerMode.kJointImpedance, MoveMotionGeneratorMode.kJointVelocity),
    # Robot::control's default controller mode for a motion generator: kJointImpedance.
    "cartesian_pose": (
        MoveControllerMode.kJointImpedance,
        MoveMotionGeneratorMode.kCartesianPosition,
    ),
    "cartesian_velocity": (
        MoveControllerMode.kJointImpedance,
        MoveMotionGeneratorMode.kCartesianVelocity,
    ),
    "torque": (MoveControllerMode.kExternalController, MoveMotionGeneratorMode.kNone),
}
_FIELD = {
    "joint_position": "q_c",
    "joint_velocity": "dq_c",
    "cartesian_pose": "O_T_EE_c",
    "cartesian_velocity": "O_dP_EE_c",
    "torque": "tau_J_d",
}
#: libfranka reads states after Move until the modes switch, and one more, sending nothing.
SILENT_CYCLES = 2
_MODE_NAMES = {int(m): m.name for m in RobotMode}


def draw_episode(rng: np.random.Generator, noise: float, task) -> tuple[np.ndarray, np.ndarray]:
    """An episode's start pose (the home pose plus uniform noise of +-``noise`` rad per
    joint) and its goal (``task.sample_goal``), drawn from ``rng`` in that order: what a
    reset draws, and what examples/deploy_pylibfranka.py draws for the same reaches."""
    start = HOME_Q + rng.uniform(-noise, noise, size=7)
    return start, task.sample_goal(rng)


class FciBatch:
    """n reach episodes on n simulated FR3s, stepped together (see the module docstring).

    The arguments are FrankaFCIEnv's (its docstring describes them); ``channel`` may
    also be a list with one model or spec per arm (a single ``Channel`` instance is
    copied per arm: every arm gets its own link and its own random stream).
    """

    def __init__(
        self,
        n: int,
        action_interface: str = "joint_position",
        action_filter: str = "limit_rate",
        policy_hz: float = 25.0,
        max_episode_steps: int = 50,
        reward_type: str = "sparse",
        distance_threshold: float = 0.05,
        enforce_motion_limits: bool = True,
        enforce_comm_constraints: bool = True,
        channel: Channel | str | None | list = None,
        reset_noise: float = 0.05,
        robot: str = "fr3",
        gripper: bool = False,
        gripper_speed: float = 0.1,
        cartesian_dof: int = 6,
        cartesian_limits: str | tuple[float, ...] = "conservative",
        reset_mode: str = "teleport",
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
        self.max_episode_steps = int(max_episode_steps)
        self.reset_noise = float(reset_noise)
        self.task = Reach(reward_type=reward_type, distance_threshold=distance_threshold)
        self.config = ControllerConfig(
            robot=robot,
            enforce_motion_limits=enforce_motion_limits,
            enforce_comm_constraints=enforce_comm_constraints,
        )
        self.gripper = bool(gripper)
        self.gripper_speed = float(gripper_speed)
        self.hands = [FrankaHand() for _ in range(n)] if self.gripper else None
        self.controller = FciController(ArmPhysics(n_arms=n, hand=self.gripper), self.config)
        self.channels = _channels(channel, n)
        self._perfect = all(type(c) is Channel for c in self.channels)
        self.commands = CommandGenerator(
            action_interface,
            action_filter,
            self.cycles_per_step,
            self.config.table,
            n=n,
            cartesian_dof=cartesian_dof,
            cartesian_limits=cartesian_limits,
        )
        self._dim = self.commands.action_dim
        #: the spaces of one arm
        self.action_space = spaces.Box(
            -1.0, 1.0, shape=(self._dim + 1 if gripper else self._dim,), dtype=np.float32
        )
        self.observation_space = observation_space(self.config.table, self.gripper)
        self._command = np.zeros(n, dtype=ROBOT_COMMAND_DTYPE)
        self._all = np.ones(n, dtype=bool)
        self._all.setflags(write=False)
        self._rounds: list[np.ndarray] = []  # per-arm channels: the k-th datagram of each arm
        self.goals = np.zeros((n, 3))
        self.steps = np.zeros(n, dtype=np.int64)
        self.cycles = np.zeros(n, dtype=np.int64)  # cycles of each arm's episode
        self.lost_run = np.zeros(n, dtype=np.int64)
        self.longest_lost = np.zeros(n, dtype=np.int64)
        self._fresh = np.zeros(n, dtype=bool)  # reset, its silent cycles still to come

    # -- episodes ------------------------------------------------------------------------------

    def reset_arms(self, arms, rngs: list[np.random.Generator]) -> None:
        """Start new episodes on ``arms``, each drawing from its own ``rngs[i]`` (indexed by
        arm): teleport to the home pose plus seeded noise (or go there through the FCI:
        ``reset_mode="fci"``), Move, draw a goal."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        ctrl = self.controller
        drawn = [draw_episode(rngs[i], self.reset_noise, self.task) for i in arms.tolist()]
        q = np.stack([start for start, _ in drawn])
        if self.reset_mode == "fci":  # recovery and a joint motion home (one arm)
            reset_through_fci(ctrl, q[0])
        else:
            ids = ctrl.writer.message_id.copy()
            ctrl.reset(arms, q)
            # The reset publishes the teleported state under a new message id, for every
            # arm. The other arms' datagrams still in flight (a delayed channel) would then
            # look one cycle older than they are: keep the ids, so a reset of arm i never
            # touches arm j.
            ctrl.writer.message_id[...] = ids
            ctrl.states["message_id"] = ids
        controller_mode, generator = MOVE[self.action_interface]
        for i in arms.tolist():
            self.channels[i].reset(rngs[i])
            if self.gripper and self.reset_mode == "teleport":
                self.hands[i] = FrankaHand()  # open (the physics fingers were reset open too)
            ctrl.move(i, int(controller_mode), int(generator))
        self.goals[arms] = [goal for _, goal in drawn]
        self.commands.reset(arms)
        self.steps[arms] = 0
        self.cycles[arms] = 0
        self.lost_run[arms] = 0
        self.longest_lost[arms] = 0
        self._fresh[arms] = True

    def observe(self) -> tuple[dict, dict]:
        """Observations and infos of every arm as they stand (after a reset: lost 0)."""
        states, ee, width = self._measured()
        zeros = np.zeros(self.n, dtype=np.int64)
        no_violations = np.zeros((self.n, self.controller.errors.shape[1]), dtype=bool)
        obs = self._observation(states, ee, width)
        return obs, self._info(states, ee, zeros, no_violations, np.zeros(self.n))

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
            self._command_hands(a[:, self._dim], active)
            a = a[:, : self._dim]
        state = ctrl.states
        gen = self.commands
        gen.begin_step(a, state)
        fresh = self._fresh & active
        self._fresh[active] = False
        frozen = np.zeros(n, dtype=bool)
        violations = np.zeros((n, ctrl.errors.shape[1]), dtype=bool)
        lost = np.zeros(n, dtype=np.int64)
        snapshot = None
        # Only the id and the active field change from cycle to cycle (the rest of the
        # command stays zero, as libfranka sends it).
        command = self._command
        command_id, command_field = command["message_id"], command[_FIELD[self.action_interface]]
        published = state["message_id"]
        sending = active & ~fresh
        everyone = bool(sending.all())
        mask = self._all if everyone else sending
        k = -1
        for k in range(self.cycles_per_step):
            if k == SILENT_CYCLES and fresh.any():
                sending = active & ~frozen
                everyone = bool(sending.all())
                mask = self._all if everyone else sending
            command_id[...] = published
            command_field[...] = gen.command(state, k, None if everyone else sending)
            if self._perfect:
                ctrl.receive(command, mask)
            else:
                self._transmit(command, sending, lost)
            if self.gripper:
                self._step_hands(active & ~frozen)
            events = ctrl.step()
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
        states, ee, width = self._measured(frozen, snapshot)
        obs = self._observation(states, ee, width)
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
        return obs, reward, terminated, truncated, self._info(states, ee, lost, violations, penalty)

    # -- internals -----------------------------------------------------------------------------

    def _freeze(self, ended, k, frozen, active, violations, snapshot):
        ctrl = self.controller
        running = active & ~frozen
        violations[running] |= ctrl.violations.take()[running]
        frozen[ended] = True
        self.cycles[ended] += k + 1
        if snapshot is None:
            snapshot = (ctrl.states.copy(), np.zeros((self.n, 3)), np.zeros(self.n))
        snapshot[0][ended] = ctrl.states[ended]
        snapshot[1][ended] = ctrl.writer.O_T_EE[ended, 12:15]
        if self.gripper:
            snapshot[2][ended] = ctrl.physics.finger_width()[ended]
        return snapshot

    def _measured(self, frozen=None, snapshot=None):
        """The states, EE positions (float64) and hand widths, frozen rows from the snapshot."""
        ctrl = self.controller
        states = ctrl.states
        ee = ctrl.writer.O_T_EE[:, 12:15].copy()
        width = ctrl.physics.finger_width() if self.gripper else None
        if snapshot is not None:
            states = states.copy()
            states[frozen] = snapshot[0][frozen]
            ee[frozen] = snapshot[1][frozen]
            if width is not None:
                width = np.where(frozen, snapshot[2], width)
        return states, ee, width

    def _observation(self, states, ee, width) -> dict[str, np.ndarray]:
        return build_observation(
            self.observation_space,
            states["q"],
            states["dq"],
            ee,
            self.goals,
            states["O_dP_EE_c"],
            width,
        )

    def _info(self, states, ee, lost, violations, penalty) -> dict[str, np.ndarray]:
        return {
            "errors": _names(states["errors"]),
            "reflex_reason": _names(states["reflex_reason"]),
            "robot_mode": _objects([_MODE_NAMES[m] for m in states["robot_mode"].tolist()]),
            "control_command_success_rate": states["control_command_success_rate"].astype(
                np.float64
            ),
            "lost_cycles": lost,
            "longest_lost_run": self.longest_lost.copy(),
            "violations": _names(violations),
            "cycles": self.cycles.copy(),
            "is_success": np.asarray(self.task.is_success(ee, self.goals), dtype=bool),
            "reflex_penalty": penalty,
        }

    def _transmit(self, command: np.ndarray, sending: np.ndarray, lost: np.ndarray) -> None:
        """Per-arm channels: each arm's datagrams reach the robot in their own order."""
        n = self.n
        open_ids = command["message_id"].copy()
        answered = np.zeros(n, dtype=bool)
        rounds: list[list[tuple[int, np.ndarray]]] = []
        for i in np.flatnonzero(sending).tolist():
            for r, delivered in enumerate(self.channels[i].transmit(command[i : i + 1])):
                if r == len(rounds):
                    rounds.append([])
                rounds[r].append((i, delivered))
        for r, deliveries in enumerate(rounds):
            if r == len(self._rounds):
                self._rounds.append(np.zeros(n, dtype=ROBOT_COMMAND_DTYPE))
            batch, mask = self._rounds[r], np.zeros(n, dtype=bool)
            for i, delivered in deliveries:
                batch[i] = delivered[0]
                mask[i] = True
                answered[i] |= bool(delivered["message_id"][0] == open_ids[i])
            self.controller.receive(batch, mask)
        # A cycle is lost when no command answering it reached the robot in time.
        missed = sending & ~answered
        lost += missed
        self.lost_run[sending] = np.where(answered[sending], 0, self.lost_run[sending] + 1)
        np.maximum(self.longest_lost, self.lost_run, out=self.longest_lost)

    def _command_hands(self, width_actions: np.ndarray, active: np.ndarray) -> None:
        targets = (np.clip(width_actions, -1.0, 1.0) + 1.0) / 2.0 * MAX_WIDTH
        for i in np.flatnonzero(active).tolist():
            if abs(targets[i] - self.hands[i].width) > 1e-6:
                self.hands[i].move(targets[i], self.gripper_speed)

    def _step_hands(self, moving: np.ndarray) -> None:
        arms = np.flatnonzero(moving)
        for i in arms.tolist():
            self.hands[i].step(1e-3)
        self.controller.physics.set_finger_width(arms, [self.hands[i].width for i in arms])


def _channels(spec, n: int) -> list[Channel]:
    if isinstance(spec, (list, tuple)):
        if len(spec) != n:
            raise ValueError(f"channel: a list needs one entry per arm ({n}), got {len(spec)}")
        channels = [make_channel(s) for s in spec]
    else:
        channel = make_channel(spec)
        channels = [channel] + [copy.deepcopy(channel) for _ in range(n - 1)]
    if len({id(c) for c in channels}) != n:
        raise ValueError("channel: every arm needs a Channel instance of its own")
    return channels


def _objects(values: list) -> np.ndarray:
    out = np.empty(len(values), dtype=object)
    out[:] = values
    return out


def _names(bits: np.ndarray) -> np.ndarray:
    """Per row of (n, 41) error bits: the tuple of the robot's error names."""
    out = np.empty(len(bits), dtype=object)
    out.fill(())
    for i in np.flatnonzero(bits.any(axis=1)).tolist():
        out[i] = error_names(bits[i])
    return out


def info_row(info: dict[str, np.ndarray], i: int) -> dict:
    """One arm's info as a single env reports it (Python scalars and tuples); the vector
    layout's ``_key`` masks are left out."""
    return {
        key: (value[i] if value.dtype == object else value[i].item())
        for key, value in info.items()
        if not key.startswith("_")
    }
