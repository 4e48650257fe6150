"""The physics Franka Hand (``--gripper-physics``): MuJoCo fingers, polled until they settle.

The fingers live in the robot server's MuJoCo world (the hand on the flange,
models/hand.xml) and move on the tick thread through a
:class:`~franka_sim_gym.sim.finger_drive.FingerDrive`. This class is the
gripper server's side: it turns Homing/Move/Grasp/Stop into drive commands and
decides, from the samples it polls, when an action is over and how it went:

* an action is *settled* after ``SETTLE_POLLS`` consecutive fresh polls of
  near-zero finger velocity (docs/fci-behaviour.md "Command coverage": never a single one,
  closing fingers pass through momentary quiet samples), taken once the ramp
  has ended or the fingers are stalled — otherwise a motion would "settle"
  before it started, while the fingers are still at rest;
* an action not settled ``SETTLE_TIMEOUT`` (docs/fci-behaviour.md "Command coverage": 4 s) after its
* ramp's
  nominal end is ended there (logged) and judged like a settled one;
* a grasp is judged by libfranka's epsilon test on the stall width, a move or
  homing by reaching its target within ``MOVE_TOLERANCE``;
* is_grasped is set as soon as a poll sees the fingers stalled inside the
  epsilon band, before the grasp settles and is answered.
"""

from __future__ import annotations

import logging

from .finger_drive import GRASP_OVERTRAVEL, FingerDrive, FingerSample
from .gripper import HandModel, Outcome, _Action

log = logging.getLogger("franka_sim_gym.gripper")

#: docs/fci-behaviour.md "Command coverage": three consecutive near-zero-velocity polls.
SETTLE_POLLS = 3
#: "Near zero" finger velocity [m/s of width]: a settling servo (~130 rad/s)
#: moving this slowly is within ~10 um of where it stops.
SETTLE_SPEED = 0.001
#: docs/fci-behaviour.md "Command coverage": 4 s timeout, counted here from the end of the
#: ramp so a slow commanded speed is not cut short.
SETTLE_TIMEOUT = 4.0
#: A settled move or homing within this of its target succeeded; farther, it
#: was blocked (the real hand's tolerance is not documented; the servo settles
#: within ~10 um, an object blocks it by millimetres).
MOVE_TOLERANCE = 0.001


class PhysicsHand(HandModel):
    """The Franka Hand whose fingers are MuJoCo bodies driven by ``drive``.

    Args:
        drive: the finger drive the robot server's tick thread runs.
        object_width: the width of the virtual object built into the world
            (reported only: the object itself is a MuJoCo geom between the
            fingertips, see sim/world.py).
    """

    def __init__(self, drive: FingerDrive, object_width: float | None = None) -> None:
        super().__init__(object_width)
        self.drive = drive
        self._seq = 0
        self._quiet = 0
        self._last_time = -1.0
        self._deadline: float | None = None
        self._ramp_seconds = 0.0

    @property
    def width(self) -> float:
        """The measured opening [m] of the latest tick."""
        return self.drive.sample.width

    def _begin(self, action: _Action) -> None:
        grasp = action.kind == "grasp"
        target = -GRASP_OVERTRAVEL if grasp else action.target
        self._seq = self.drive.command(target, action.speed, action.force, squeeze=grasp)
        self._quiet = 0
        self._deadline = None
        self._ramp_seconds = abs(target - self.width) / action.speed

    def _halt(self) -> None:
        # Hold the width the fingers are at when the tick reads the command.
        self._seq = self.drive.command(None, 0.0)

    def step(self, dt: float) -> None:
        """Poll the latest sample (``dt`` is unused: the fingers move in simulated time)."""
        action = self._action
        sample = self.drive.sample
        if action is None or sample.seq < self._seq or sample.time <= self._last_time:
            return  # the tick has not applied the command yet, or no new sample
        self._last_time = sample.time
        if self._deadline is None:
            self._deadline = sample.time + self._ramp_seconds + SETTLE_TIMEOUT
        grasp = action.kind == "grasp"
        if grasp and sample.stalled:
            self.is_grasped = self._grasped(sample.width)
        quiet = abs(sample.velocity) < SETTLE_SPEED and (sample.ramp_done or sample.stalled)
        self._quiet = self._quiet + 1 if quiet else 0
        if self._quiet >= SETTLE_POLLS:
            self._settle(action, sample)
        elif sample.time >= self._deadline:
            log.warning(
                "gripper-settle-timeout: %s (action %d) not settled %.1f s after its ramp; "
                "judged at width %.4f m (velocity %.4f m/s)",
                action.kind,
                action.id,
                SETTLE_TIMEOUT,
                sample.width,
                sample.velocity,
            )
            self._settle(action, sample)

    def _settle(self, action: _Action, sample: FingerSample) -> None:
        if action.kind == "grasp":
            self.is_grasped = self._grasped(sample.width)
            self._finish(Outcome.SUCCESS if self.is_grasped else Outcome.UNSUCCESSFUL)
        elif abs(sample.width - action.target) <= MOVE_TOLERANCE:
            self._finish(Outcome.SUCCESS)
        else:
            # Blocked short of the target (the object): as the kinematic backend.
            self._finish(Outcome.UNSUCCESSFUL)
