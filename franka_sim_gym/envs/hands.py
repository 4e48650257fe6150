"""The env's Franka Hands: what the task needs of them, the width action, and the load of
what they hold.

A task names its hand (``Task.hand``, envs/tasks/base.py): none (the ``gripper``
argument decides), ``"grasp"`` (a width action), ``"closed"`` (squeezed shut) or
``"held"`` (squeezing what the task put between the fingers). Every arm's fingers run
on the batched force-limited servo (sim/finger_drive.FingerServos: the gripper server's
ramp, stall and squeeze rules); ``configure_load`` configures a held object's mass as the
robot's load (SetLoad) while both fingertips touch it.
"""

from __future__ import annotations

import numpy as np

from ..fci.controller import FciController
from ..fci.wire.statuses import SetterStatus
from ..sim.arm import ArmPhysics
from ..sim.finger_drive import FingerServos
from ..sim.gripper import MAX_WIDTH
from ..sim.hand_load import HeldObjects

#: The hands a task may need (Task.hand): None leaves it to the ``gripper`` argument.
HANDS = (None, "grasp", "closed", "held")


def hand_choice(task_name: str, hand: str | None, gripper: bool | None) -> tuple[bool, bool]:
    """(a width action, a hand mounted) for a task's ``hand`` and the env's ``gripper``
    argument (None: the task's choice); a ValueError names a contradiction."""
    if hand not in HANDS:
        raise ValueError(f"{task_name}.hand {hand!r}: expected one of {HANDS}")
    if hand in ("closed", "held") and gripper:
        raise ValueError(f"gripper: {task_name} holds the fingers itself (no width action)")
    width_action = hand == "grasp" if gripper is None else bool(gripper)
    return width_action, width_action or hand is not None


class EnvHands:
    """The hands of the n arms of one env world (see the module docstring).

    Args:
        physics: the world, built with hands.
        hand: the task's ``hand``.
        held_object: the task's ``held_object`` (a free joint of its scene) or None.
        gripper_speed, grasp_force, configure_load: the env's arguments.
    """

    def __init__(
        self,
        physics: ArmPhysics,
        hand: str | None,
        held_object: str | None,
        gripper_speed: float,
        grasp_force: float,
        configure_load: bool,
    ) -> None:
        if not (np.isfinite(grasp_force) and 0.0 < grasp_force <= 100.0):
            raise ValueError(f"grasp_force must be in (0, 100] N, got {grasp_force!r}")
        self.physics = physics
        self.hand = hand
        self.speed = float(gripper_speed)
        self.grasp_force = float(grasp_force)
        self.configure_load = bool(configure_load)
        #: every arm's fingers on the force-limited servo
        self.servos = FingerServos(physics)
        self._targets = np.full(physics.n, np.nan)
        #: the object each hand may hold (None: the task holds nothing)
        self.held = None
        if held_object is not None:
            bodies = physics.layout.scene_body[held_object]
            self.held = HeldObjects(physics.model, physics.layout, bodies)
        #: (n,) the held object's load is configured on the robot
        self.load_configured = np.zeros(physics.n, dtype=bool)

    def width(self) -> np.ndarray:
        """(n,) the measured opening [m]."""
        return self.servos.width()

    def before_task_reset(self, arms: np.ndarray, width_action: bool, teleported: bool) -> None:
        """A closed hand shut; a hand with a width action open, as the teleport left it."""
        lay = self.physics.layout
        if self.hand == "closed":
            for i in np.asarray(arms).tolist():
                data = self.physics.datas[i]
                data.qpos[lay.finger_qpos_adr[i]] = 0.0
                data.qvel[lay.finger_dof_adr[i]] = 0.0
        elif width_action and teleported:
            self.servos.command(arms, MAX_WIDTH, self.speed)
            self._targets[arms] = MAX_WIDTH

    def after_task_reset(self, arms: np.ndarray) -> None:
        """Closed and holding hands squeeze; the reset cleared SetLoad: configure it anew."""
        if self.hand in ("closed", "held"):
            self.servos.hold(arms, self.grasp_force)
        self.load_configured[arms] = False

    def command(self, width_actions: np.ndarray, active: np.ndarray) -> None:
        """A new width target is a new command of the servo: closing is a grasp
        (force-limited at ``grasp_force``; a stall squeezes), opening a move."""
        targets = (np.clip(width_actions, -1.0, 1.0) + 1.0) / 2.0 * MAX_WIDTH
        new = active & ~(np.abs(targets - self._targets) <= 1e-6)
        arms = np.flatnonzero(new)
        if not len(arms):
            return
        self._targets[arms] = targets[arms]
        closing = targets[arms] < self.servos.width()[arms]
        for rows, force in ((closing, self.grasp_force), (~closing, None)):
            self.servos.command(arms[rows], targets[arms[rows]], self.speed, force, closing[rows])

    def tick(self, moving: np.ndarray) -> None:
        """One cycle of the servos of the ``moving`` arms."""
        self.servos.tick(np.flatnonzero(moving))

    def configure_loads(self, ctrl: FciController, arms: np.ndarray) -> None:
        """``configure_load``: SetLoad with the held object's mass while a hand holds it,
        SetLoad(0) when it lets go (what a careful robot program does after a grasp)."""
        if self.held is None or not self.configure_load or not len(arms):
            return
        datas = self.physics.datas
        held = self.held.held(datas)
        for i in arms[held[arms] != self.load_configured[arms]].tolist():
            if held[i]:
                status = ctrl.set_load(i, *self.held.load(datas[i], i))
            else:
                status = ctrl.set_load(i, 0.0, np.zeros(3), np.zeros(9))
            if status != SetterStatus.kSuccess:  # pragma: no cover - the model's values
                raise RuntimeError(f"robot {i} refused SetLoad: {status}")
            self.load_configured[i] = held[i]
