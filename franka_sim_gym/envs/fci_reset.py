"""A reset a real robot could do: recover from a reflex, then a joint motion to the start.

The env's default reset teleports the arm (``FciController.reset``). With
``reset_mode="fci"`` it goes through the FCI instead, as a user's script on a
real FR3 would between episodes (issue "Gymnasium env", item 5): StopMove if a
motion is still running, AutomaticErrorRecovery if a reflex is latched (the
reply waits for standstill, docs/fci-behaviour.md "Enabling the violation"), then a
joint-position Move whose waypoints follow a quintic from where the arm stands
to the episode's start pose, streamed one per cycle and judged by the robot's
own checks like any client's. The configured frames (SetNEToEE, SetLoad) are
kept, as they are on the robot.

The reset runs over a perfect link (it is the user's reset code, not the
policy's), in-process and deterministic. It needs the whole world: one arm.
"""

from __future__ import annotations

import math

import numpy as np

from ..fci.controller import FciController
from ..fci.events import EventKind
from ..fci.wire import (
    ROBOT_COMMAND_DTYPE,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    RobotMode,
)
from ..fci.wire.protocol import MoveStatus

#: The home trajectory's peak joint velocity [rad/s], acceleration [rad/s^2] and
#: jerk [rad/s^3]: well inside the FR3's 2.62 rad/s (joints 1-4), 10 rad/s^2 and
#: 5000 rad/s^3 (docs/limits.md §1.1), so a move home never trips a limit (13/14/15).
HOME_VELOCITY = 1.0
HOME_ACCELERATION = 4.0
HOME_JERK = 400.0

#: Quintic s(t) = 10 t^3 - 15 t^4 + 6 t^5 on [0, 1]: its peak |s'|, |s''|, |s'''|.
_PEAK_VELOCITY = 1.875
_PEAK_ACCELERATION = 10.0 / math.sqrt(3.0)
_PEAK_JERK = 60.0


class FciResetError(RuntimeError):
    """The robot refused or aborted the reset (the message names what and why)."""


def home_duration(distance: float) -> float:
    """Seconds of the quintic that covers ``distance`` [rad] (the largest joint's)
    within HOME_VELOCITY, HOME_ACCELERATION and HOME_JERK, whole milliseconds."""
    t = max(
        _PEAK_VELOCITY * distance / HOME_VELOCITY,
        math.sqrt(_PEAK_ACCELERATION * distance / HOME_ACCELERATION),
        (_PEAK_JERK * distance / HOME_JERK) ** (1.0 / 3.0),
        0.01,
    )
    return math.ceil(t * 1000.0) / 1000.0


def quintic(tau: np.ndarray) -> np.ndarray:
    """s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5: 0 to 1 with zero velocity and acceleration
    at both ends."""
    return tau**3 * (10.0 + tau * (-15.0 + 6.0 * tau))


def reset_through_fci(ctrl: FciController, q_start: np.ndarray) -> int:
    """Bring robot 0 of ``ctrl`` (a world of one arm) to ``q_start`` the way a client
    would; returns the cycles it took. Raises FciResetError naming the robot's errors
    when a step is refused or aborted."""
    if ctrl.n != 1:
        raise ValueError(f"reset through the FCI needs a world of one arm, got {ctrl.n}")
    cycles = 0
    if ctrl.in_motion[0]:
        ctrl.stop_move(0)
    if int(ctrl.robot_mode[0]) == int(RobotMode.kReflex):
        if ctrl.automatic_error_recovery(0) is not None:
            raise FciResetError("AutomaticErrorRecovery was refused")
        cycles += _until(ctrl, EventKind.RECOVERY_FINISHED, ctrl.config.recovery_max_cycles + 1)
    cycles += _settle(ctrl)
    status = ctrl.move(
        0, int(MoveControllerMode.kJointImpedance), int(MoveMotionGeneratorMode.kJointPosition)
    )
    if status != MoveStatus.kMotionStarted:
        raise FciResetError(f"the move home was refused: {status.name}")
    q0 = ctrl.states["q_d"][0].astype(np.float64)
    delta = np.asarray(q_start, dtype=np.float64).reshape(7) - q0
    steps = round(home_duration(float(np.abs(delta).max())) * 1000.0)
    command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
    mask = np.ones(1, dtype=bool)
    # The first waypoint is q_d itself (the start-pose check), the last the target.
    for k, s in enumerate(quintic(np.arange(steps + 1) / steps).tolist()):
        command["q_c"][0] = q0 + delta * s
        command["message_id"] = ctrl.states["message_id"]
        command["motion_generation_finished"] = k == steps
        ctrl.receive(command, mask)
        events = ctrl.step()
        cycles += 1
        for event in events:
            if event.kind is EventKind.MOVE_FINISHED:
                if event.status != MoveStatus.kSuccess:
                    names = ", ".join(ctrl.error_names(0)) or "no error"
                    raise FciResetError(
                        f"the move home ended {MoveStatus(event.status).name} ({names})"
                    )
                return cycles + _settle(ctrl)
    raise FciResetError("the move home did not finish")  # pragma: no cover


def _until(ctrl: FciController, kind: EventKind, limit: int) -> int:
    """Idle cycles until an event of ``kind`` for robot 0 (at most ``limit``)."""
    for k in range(1, limit + 1):
        if any(e.kind is kind for e in ctrl.step()):
            return k
    raise FciResetError(f"no {kind.name} within {limit} cycles")


def _settle(ctrl: FciController) -> int:
    """Idle cycles until the state's dq says the arm stands still by the thresholds
    AutomaticErrorRecovery uses, or its 0.7 s cap (a client reads the state, as here)."""
    cfg = ctrl.config
    settled = 0
    for k in range(1, cfg.recovery_max_cycles + 1):
        if float(np.abs(ctrl.states["dq"][0]).max()) < cfg.recovery_velocity_threshold:
            settled += 1
            if settled >= cfg.recovery_settle_cycles:
                return k
        else:
            settled = 0
        ctrl.step()
    return cfg.recovery_max_cycles
