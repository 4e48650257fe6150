"""The physics hand's finger drive, run on the robot server's 1 kHz tick thread.

The gripper server never touches MuJoCo: it posts a :class:`DriveCommand`
(:meth:`FingerDrive.command`, any thread) and reads the latest
:class:`FingerSample` (:attr:`FingerDrive.sample`). Both are immutable objects
swapped in by one attribute assignment, which is atomic in CPython, so neither
side takes a lock and the tick thread never waits for the gripper.

Each tick (:meth:`FingerDrive.tick`, after the world stepped):

* a reference width ramps from where the fingers were when the command
  arrived towards its target at the commanded speed (the real hand moves at
  the commanded speed), and the fingers' ``position`` servo (models/hand.xml,
  PD, per finger = half the width) tracks it, with the ramp's velocity fed
  forward through the servo's damping term so the fingers do not lag it;
* the servo's force range is the command's force: the commanded grasp force
  is a limit on the finger force (docs/gripper.md "Two backends, one protocol" (grasp force), closed
  here);
* the fingers are *stalled* when the reference is more than ``STALL_LEAD``
  ahead of them (something blocks them: the object, or the other finger);
* a grasp, once stalled, squeezes: the reference jumps far past the fingers so
  the servo saturates at the force limit and holds the object with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .arm import ArmPhysics

#: The fingers count as blocked when the ramp leads them by this much [m of
#: width]. Free fingers track the fed-forward ramp within ~0.3 mm at 0.1 m/s
#: (a velocity step into a servo of natural frequency sqrt(1000 / 0.058) ≈ 130
#: rad/s), so 2 mm is never reached in free motion below ~0.5 m/s.
STALL_LEAD = 0.002
#: A grasp's ramp ends this far below 0 m [m of width], so that in thin air the
#: fingers stall on each other at 0 like on an object (and squeeze there).
GRASP_OVERTRAVEL = 2 * STALL_LEAD
#: How far [m per finger] the squeezing reference lies below force / kp: from
#: any finger position (>= 0) the servo then asks for more than the force
#: limit, by kp * 0.1 = 100 N, and the force range clamps it to the limit.
_SQUEEZE_MARGIN = 0.1


@dataclass(frozen=True)
class DriveCommand:
    """What the fingers should do; ``seq`` orders commands (a new one restarts the ramp).

    Attributes:
        seq: command counter, assigned by :meth:`FingerDrive.command`.
        target: width [m] the ramp ends at; None holds the width the fingers
            are at when the command arrives (Stop).
        speed: ramp speed [m/s] (0 with a None target).
        force: finger force limit [N].
        squeeze: saturate the drive at ``force`` once the fingers stall (Grasp).
    """

    seq: int
    target: float | None
    speed: float
    force: float
    squeeze: bool = False


@dataclass(frozen=True)
class FingerSample:
    """The fingers after one tick, as the gripper polls them.

    Attributes:
        time: simulated time [s] of the sample.
        width: opening [m], the two finger joints summed.
        velocity: d(width)/dt [m/s].
        seq: the command in force when the sample was taken.
        ramp_done: the reference has reached the command's target.
        stalled: the fingers are blocked (or a grasp squeezes).
    """

    time: float
    width: float
    velocity: float
    seq: int
    ramp_done: bool
    stalled: bool


class FingerDrive:
    """Drives one arm's hand fingers inside the server's MuJoCo world.

    Args:
        physics: the world, built with ``hand=True``; owned by the tick thread.
        arm: which arm's hand.
        force: the drive's force limit [N] for motions that give none
            (default: the model's actuator force range, the URDF's 100 N effort).
    """

    def __init__(self, physics: ArmPhysics, arm: int = 0, force: float | None = None) -> None:
        layout = physics.layout
        if layout.finger_actuator is None:
            raise ValueError("the physics gripper needs a hand: ArmPhysics(hand=True)")
        self._model, self._data = physics.model, physics.data
        self._act = int(layout.finger_actuator[arm])
        self._qpos = [int(a) for a in layout.finger_qpos_adr[arm]]
        self._dof = [int(a) for a in layout.finger_dof_adr[arm]]
        model = self._model
        kp = float(model.actuator_gainprm[self._act, 0])
        kv = -float(model.actuator_biasprm[self._act, 2])
        #: Velocity feed-forward through a position servo: kp (ctrl - q) - kv dq
        #: with ctrl = ref + (kv / kp) dref is kp (ref - q) + kv (dref - dq).
        self._feed_forward = kv / kp
        self._kp = kp
        self._dt = float(model.opt.timestep)
        #: Force of Homing / Move / Stop (the grasp brings its own).
        limit = model.actuator_forcerange[self._act, 1] if force is None else force
        self.default_force = float(limit)
        # The reference may leave the 0..0.04 m joint range (feed-forward, the
        # grasp's overtravel and squeeze): the joint's range stops the fingers.
        model.actuator_ctrlrange[self._act] = (-math.inf, math.inf)
        width, _ = self._measure()
        self._seq = 0
        self._command = DriveCommand(seq=0, target=None, speed=0.0, force=self.default_force)
        self._ref = self._target = width
        self._squeezing = False
        self._applied = -1
        #: The latest sample; replaced (never mutated) once per tick.
        self.sample = FingerSample(float(self._data.time), width, 0.0, 0, True, False)

    # -- the gripper's side (any thread) -----------------------------------------------------

    def command(
        self, target: float | None, speed: float, force: float | None = None, squeeze: bool = False
    ) -> int:
        """Post a new command (applied at the next tick); returns its ``seq``."""
        self._seq += 1
        self._command = DriveCommand(
            self._seq, target, speed, self.default_force if force is None else force, squeeze
        )
        return self._seq

    # -- the tick thread ---------------------------------------------------------------------

    def tick(self) -> None:
        """Apply the current command for the next step and publish this step's sample."""
        width, velocity = self._measure()
        cmd = self._command
        if cmd.seq != self._applied:
            self._applied = cmd.seq
            self._ref = width  # start from where the fingers are: no jump in force
            self._target = width if cmd.target is None else cmd.target
            self._squeezing = False
            self._model.actuator_forcerange[self._act] = (-cmd.force, cmd.force)
        gap = self._target - self._ref
        delta = cmd.speed * self._dt
        if abs(gap) <= delta:
            self._ref, ref_velocity = self._target, 0.0
        else:
            self._ref += math.copysign(delta, gap)
            ref_velocity = math.copysign(cmd.speed, gap)
        stalled = abs(self._ref - width) > STALL_LEAD
        if cmd.squeeze and stalled:
            self._squeezing = True
        if self._squeezing:
            ctrl = -(cmd.force / self._kp + _SQUEEZE_MARGIN)
        else:
            ctrl = (self._ref + self._feed_forward * ref_velocity) / 2.0  # per finger
        self._data.ctrl[self._act] = ctrl
        self.sample = FingerSample(
            float(self._data.time),
            width,
            velocity,
            cmd.seq,
            self._ref == self._target,
            stalled or self._squeezing,
        )

    def _measure(self) -> tuple[float, float]:
        q, dq = self._data.qpos, self._data.qvel
        a, b = self._qpos
        c, d = self._dof
        return float(q[a] + q[b]), float(dq[c] + dq[d])
