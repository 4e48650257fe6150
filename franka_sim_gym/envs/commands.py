"""From a policy action to one command per 1 ms cycle: the libfranka client's job.

The env plays the client between policy steps; the deploy script
(examples/deploy_pylibfranka.py) imports this same module to drive a real
libfranka client, so a policy meets the same command stream in training and on
the robot. Filters (``action_filter``):

* ``"none"`` — the action's target is held for every cycle of the step: what a
  naive controller sends (and the reason it trips reflexes);
* ``"interpolate"`` — linear interpolation from the reference at the start of
  the step to the target, across the step's cycles;
* ``"lowpass"`` — libfranka's first-order low-pass (100 Hz, Robot::control's
  default) against the state's reference;
* ``"limit_rate"`` — the low-pass followed by libfranka's rate limiter
  (Robot::control with ``limit_rate = true``), which keeps every command inside
  the robot's velocity, acceleration and jerk limits.

All filters read the robot's own references from the state (q_d, dq_d, ddq_d,
tau_J_d), exactly as libfranka's ControlLoop::convertMotion does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fci.tables import FR3, RobotTable
from . import client_filters as cf

INTERFACES = ("joint_position", "joint_velocity", "torque")

#: The rate limiter's targets sit this far inside the robot's thresholds. The
#: seed's thresholds (kMaxJointAcceleration = 10 - 1e-3, kMaxJointJerk = 5000 - 1e-3,
#: kMaxTorqueRate = 1000 - 1e-3, the URDF envelope with libfranka's 1e-3 tolerance)
#: equal libfranka's own limiter targets, and the limiter integrates from the
#: float32 references of the v10 state while the robot differences in float64:
#: the rounding (half an ulp: 1.2e-7 rad at |q| ~ 3) reaches the jerk amplified by
#: 1/dt^3, up to ~120 rad/s^3. libfranka's 1e-3 margins cannot absorb that
#: (limits.md warns about borderline comparisons); our client keeps ~6 % inside.
LIMITER_MARGIN = {"ddq": 0.3, "dddq": 300.0, "dq": 0.01, "dtau": 2.0}
FILTERS = ("none", "interpolate", "lowpass", "limit_rate")


@dataclass
class ActionScale:
    """What an action of 1.0 means per interface."""

    #: joint position: target offset from the step's starting reference [rad]
    position: float = 0.1
    #: joint velocity: target velocity [rad/s]
    velocity: float = 1.0
    #: torque: target torque without gravity [Nm], per joint
    torque: tuple[float, ...] = (20.0, 20.0, 20.0, 20.0, 4.0, 4.0, 4.0)


class CommandGenerator:
    """Turns one action per policy step into one command per cycle, for n robots.

    Args:
        interface: "joint_position", "joint_velocity" or "torque".
        action_filter: one of ``FILTERS``.
        cycles_per_step: cycles between two policy actions.
        table: the robot whose limits the rate limiter uses (libfranka's own).
        scale: the meaning of a unit action.
        cutoff: the low-pass filter's cutoff frequency [Hz].
        n: how many robots (the leading axis of actions, states and commands).
    """

    def __init__(
        self,
        interface: str,
        action_filter: str,
        cycles_per_step: int,
        table: RobotTable = FR3,
        scale: ActionScale | None = None,
        cutoff: float = cf.LOWPASS_DEFAULT_CUTOFF,
        n: int = 1,
    ) -> None:
        if interface not in INTERFACES:
            raise ValueError(f"unknown action interface {interface!r}: expected {INTERFACES}")
        if action_filter not in FILTERS:
            raise ValueError(f"unknown action_filter {action_filter!r}: expected {FILTERS}")
        self.interface = interface
        self.action_filter = action_filter
        self.cycles_per_step = cycles_per_step
        self.table = table
        self.scale = scale or ActionScale()
        self.cutoff = cutoff
        self._start = None
        self._target = None
        #: per robot: its motion's first command is still to be sent (no reference yet)
        self._first = np.ones(n, dtype=bool)
        self._n_first = n

    def reset(self, robots: np.ndarray | None = None) -> None:
        """New motions for ``robots`` (all when None): their first command is not filtered
        against a reference."""
        self._first[slice(None) if robots is None else robots] = True
        self._n_first = int(np.count_nonzero(self._first))

    def begin_step(self, action: np.ndarray, state: np.ndarray) -> None:
        """Fix the step's target from the action (n, 7) in [-1, 1] and the current state."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        if self.interface == "joint_position":
            self._start = state["q_d"].astype(np.float64)
            self._target = self._start + a * self.scale.position
        elif self.interface == "joint_velocity":
            self._start = state["dq_d"].astype(np.float64)
            self._target = a * self.scale.velocity
        else:
            self._start = state["tau_J_d"].astype(np.float64)
            self._target = a * np.asarray(self.scale.torque)

    def command(self, state: np.ndarray, k: int, sent: np.ndarray | None = None) -> np.ndarray:
        """The (n, 7) command for cycle ``k`` (0-based) of the step, given the newest state.

        ``sent`` marks the robots whose command is actually sent this cycle (None: all);
        a robot's first-command status ends only with a command sent.
        """
        if self.action_filter == "none":
            out = self._target
        elif self.action_filter == "interpolate":
            out = cf.interpolate(self._start, self._target, (k + 1) / self.cycles_per_step)
        else:
            out = self._filtered(state)
        if self._n_first:
            if sent is None:
                self._first[...] = False
            else:
                self._first &= ~sent
            self._n_first = int(np.count_nonzero(self._first))
        return out

    def _filtered(self, state: np.ndarray) -> np.ndarray:
        target = self._target
        if self.interface == "joint_position":
            ref = state["q_d"].astype(np.float64)
            if self._n_first:
                ref = np.where(self._first[:, None], target, ref)
        elif self.interface == "joint_velocity":
            ref = state["dq_d"].astype(np.float64)
        else:
            ref = state["tau_J_d"].astype(np.float64)
        out = cf.lowpass_filter(target, ref, self.cutoff)
        if self.action_filter != "limit_rate":
            return out
        t, m = self.table, LIMITER_MARGIN
        a_max, j_max = t.ddq_max - m["ddq"], t.dddq_max - m["dddq"]
        if self.interface == "joint_position":
            q_d = state["q_d"].astype(np.float64)
            upper, lower = t.velocity_envelope(q_d)
            return cf.limit_rate_joint_positions(
                out, q_d, state["dq_d"].astype(np.float64), state["ddq_d"].astype(np.float64),
                upper - m["dq"], lower + m["dq"], a_max, j_max,
            )
        if self.interface == "joint_velocity":
            upper, lower = t.velocity_envelope(state["q_d"].astype(np.float64))
            return cf.limit_rate_joint_velocities(
                out, state["dq_d"].astype(np.float64), state["ddq_d"].astype(np.float64),
                upper - m["dq"], lower + m["dq"], a_max, j_max,
            )
        tau_d = state["tau_J_d"].astype(np.float64)
        return cf.limit_rate_torques(out, tau_d, t.dtau_max - m["dtau"])
