"""In-process drivers for the controller, shaped like libfranka's control loop."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.fci.config import ControllerConfig
from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.fci.events import EventKind
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, MoveControllerMode, MoveMotionGeneratorMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from franka_sim_gym.sim.arm import ArmPhysics

JP = MoveMotionGeneratorMode.kJointPosition
JV = MoveMotionGeneratorMode.kJointVelocity
NONE = MoveMotionGeneratorMode.kNone
IMP = MoveControllerMode.kJointImpedance
EXT = MoveControllerMode.kExternalController


def make_controller(n: int = 1, **config) -> FciController:
    return FciController(ArmPhysics(n_arms=n), ControllerConfig(**config))


class LoopClient:
    """Plays libfranka for robot ``i``: Move, wait for the modes, one command per state."""

    def __init__(self, ctrl: FciController, i: int = 0) -> None:
        self.ctrl = ctrl
        self.i = i
        self.events: list = []
        self.command = np.zeros(ctrl.n, dtype=ROBOT_COMMAND_DTYPE)
        self.mask = np.zeros(ctrl.n, dtype=bool)

    @property
    def state(self):
        return self.ctrl.states[self.i]

    def idle(self, cycles: int) -> None:
        for _ in range(cycles):
            self.events += self.ctrl.step()

    def start(self, generator=JP, controller=IMP) -> MoveStatus:
        status = self.ctrl.move(self.i, int(controller), int(generator))
        if status != MoveStatus.kMotionStarted:
            return status
        # libfranka reads states until the modes switch, then one more, sending nothing.
        self.idle(2)
        return status

    def send(
        self, deliver: bool = True, message_id: int | None = None, finished: bool = False, **fields
    ) -> list:
        """One cycle: a command answering the last state (or none when not delivered)."""
        self.command[self.i] = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
        self.command["message_id"][self.i] = (
            int(self.state["message_id"]) if message_id is None else message_id
        )
        for name, value in fields.items():
            self.command[name][self.i] = value
        self.command["motion_generation_finished"][self.i] = finished
        self.command["torque_command_finished"][self.i] = finished
        self.mask[:] = False
        self.mask[self.i] = deliver
        if deliver:
            self.ctrl.receive(self.command, self.mask)
        events = self.ctrl.step()
        self.events += events
        return events

    def finish(self, **fields) -> int | None:
        """Send the final command until the motion ends; the Move's final status."""
        for _ in range(10):
            for event in self.send(finished=True, **fields):
                if event.kind is EventKind.MOVE_FINISHED:
                    return event.status
        return None

    def move_statuses(self) -> list[int]:
        return [e.status for e in self.events if e.kind is EventKind.MOVE_FINISHED]


#: Desk's Franka Hand end-effector transformation as a real robot reports it in F_T_NE
#: (column-major; libfranka include/franka/robot.h: NE is "configured outside of
#: libfranka (in DESK)"): Rz(-pi/4), 0.1034 m along the flange z axis.
DESK_HAND_F_T_NE = [0.7071, -0.7071, 0, 0, 0.7071, 0.7071, 0, 0, 0, 0, 1, 0, 0, 0, 0.1034, 1]
