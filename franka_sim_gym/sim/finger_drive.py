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

import numpy as np

from .arm import ArmPhysics
from .views import ArmRows

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
        self.physics, self._arm = physics, arm
        self._model, self._data = physics.model, physics.datas[arm]
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
            self.physics.set_finger_force(self._arm, cmd.force)
        ref, ref_velocity, stalled = ramp(self._ref, self._target, width, cmd.speed, self._dt)
        self._ref, stalled = float(ref), bool(stalled)
        if cmd.squeeze and stalled:
            self._squeezing = True
        ctrl = finger_ctrl(
            self._squeezing, cmd.force, self._kp, self._ref, self._feed_forward, ref_velocity
        )
        self._data.ctrl[self._act] = float(ctrl)
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


# -- the rules, for one hand or many ----------------------------------------------------------


def ramp(ref, target, width, speed, dt):
    """One tick of the reference ramp: (new reference, its velocity, stalled) for a hand
    or an array of them. The reference moves ``speed * dt`` towards ``target`` (and lands
    on it when closer); the fingers are stalled when it leads them by > ``STALL_LEAD``."""
    gap = np.subtract(target, ref)
    delta = np.multiply(speed, dt)
    arrived = np.abs(gap) <= delta
    ref = np.where(arrived, target, np.add(ref, np.copysign(delta, gap)))
    velocity = np.where(arrived, 0.0, np.copysign(speed, gap))
    return ref, velocity, np.abs(ref - width) > STALL_LEAD


def finger_ctrl(squeezing, force, kp, ref, feed_forward, ref_velocity):
    """The position servo's control (per finger): the ramp with its velocity fed forward,
    or, squeezing, a reference so far past the fingers that the force limit holds them."""
    follow = (np.asarray(ref) + feed_forward * np.asarray(ref_velocity)) / 2.0
    return np.where(squeezing, -(np.asarray(force) / kp + _SQUEEZE_MARGIN), follow)


class FingerServos:
    """The hands of every arm of a world on the same force-limited servo as
    :class:`FingerDrive` (the same ramp, stall and squeeze rules), batched: one call per
    tick for all hands, for the Gymnasium env (envs/core.py).

    A command per arm names a target width, a speed, a force limit and whether a stall
    squeezes (a grasp: the fingers then hold what stopped them with the force limit).

    Args:
        physics: the world, built with ``hand=True``.
        force: the force limit [N] of a motion that gives none (default: the model's
            actuator force range, the URDF's 100 N effort).
    """

    def __init__(self, physics: ArmPhysics, force: float | None = None) -> None:
        layout = physics.layout
        if layout.finger_actuator is None:
            raise ValueError("finger servos need a hand: ArmPhysics(hand=True)")
        self.physics = physics
        model = physics.model
        act0 = int(layout.finger_actuator[0])
        # every arm's finger joints and servo control, in its own MjData
        self._qpos = ArmRows([d.qpos for d in physics.datas], layout.finger_qpos_adr[0])
        self._ctrl = ArmRows([d.ctrl for d in physics.datas], layout.finger_actuator[:1])
        self._kp = float(model.actuator_gainprm[act0, 0])
        self._feed_forward = -float(model.actuator_biasprm[act0, 2]) / self._kp
        self._dt = float(model.opt.timestep)
        limit = model.actuator_forcerange[act0, 1] if force is None else force
        #: the force limit of motions that give none [N]
        self.default_force = float(limit)
        model.actuator_ctrlrange[act0] = (-math.inf, math.inf)
        n = physics.n
        self.ref = np.zeros(n)
        self.target = np.zeros(n)
        self.speed = np.zeros(n)
        self.force = np.full(n, self.default_force)
        self.squeeze = np.zeros(n, dtype=bool)
        self.squeezing = np.zeros(n, dtype=bool)
        #: (n,) the fingers are blocked (or squeezing) as of the last tick
        self.stalled = np.zeros(n, dtype=bool)

    def width(self) -> np.ndarray:
        """(n,) measured opening [m]: the two finger joints summed."""
        return self._qpos.gather().sum(axis=1)

    def command(self, arms, target, speed, force=None, squeeze=False) -> None:
        """New commands for ``arms``: the ramp starts from where the fingers are.

        A squeezing hand given another squeezing command with a target below its width
        keeps squeezing (its hold does not lapse while a policy repeats "close")."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        if not len(arms):
            return
        force = self.default_force if force is None else force
        width = self.width()[arms]
        target = np.broadcast_to(np.asarray(target, dtype=float), arms.shape)
        squeeze = np.broadcast_to(np.asarray(squeeze, dtype=bool), arms.shape)
        self.squeezing[arms] = self.squeezing[arms] & squeeze & (target < width)
        self.ref[arms] = width
        self.target[arms] = target
        self.speed[arms] = speed
        self.force[arms] = force
        self.squeeze[arms] = squeeze
        self.physics.set_finger_force(arms, self.force[arms])

    def hold(self, arms, force: float) -> None:
        """Squeeze the hands of ``arms`` closed (on what is between the fingers) with
        ``force`` from now on: a grasp whose fingers already stalled."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        self.command(arms, -GRASP_OVERTRAVEL, 0.0, force, True)
        self.ref[arms] = self.target[arms]
        self.squeezing[arms] = True
        self.stalled[arms] = True
        ctrl = finger_ctrl(True, self.force[arms], self._kp, 0.0, 0.0, 0.0)
        self._ctrl.scatter(np.broadcast_to(ctrl, arms.shape)[:, None], arms)

    def tick(self, arms) -> None:
        """Advance the ramps of ``arms`` by one step and set their servos' controls."""
        arms = np.asarray(arms, dtype=np.intp)
        if not len(arms):
            return
        q = self._qpos.gather()[arms]
        width = q[:, 0] + q[:, 1]
        ref, velocity, stalled = ramp(
            self.ref[arms], self.target[arms], width, self.speed[arms], self._dt
        )
        self.ref[arms] = ref
        squeezing = self.squeezing[arms] | (self.squeeze[arms] & stalled)
        self.squeezing[arms] = squeezing
        self.stalled[arms] = stalled | squeezing
        ctrl = finger_ctrl(squeezing, self.force[arms], self._kp, ref, self._feed_forward, velocity)
        self._ctrl.scatter(ctrl[:, None], arms)
