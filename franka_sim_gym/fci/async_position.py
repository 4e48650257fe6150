"""The robot's asynchronous joint-position generator (Move with ``use_async_motion_generator``).

libfranka's ``AsyncPositionControlHandler`` (src/async_control/async_position_control_handler.cpp,
pylibfranka's ``AsyncPositionControlHandler``) starts a joint-position Move with the async
flag and per-joint maximum velocities, then sends a joint-position *target* whenever the
user sets one (50 Hz in its example), not every millisecond. The robot's own generator
moves q_d toward the newest target; the client reads q_d and dq_d back to report
TargetReached (|q_d - target| < goal tolerance, |dq_d| < 0.01 rad/s). The robot's profile
is not published; docs/motion-limits.md "The asynchronous generator" states the one this
simulator runs:

* per joint, a velocity goal toward the target: sqrt(2 a_b |e|) far from it, |e| / T_p
  near it (a critically damped finish), capped by the client's maximum velocity and by
  a stopping-distance band inside the robot's velocity envelope (docs/limits.md §4);
* the velocity follows the goal with time constant T, the acceleration clipped to 90 %
  of kMaxJointAcceleration and its change to 90 % of kMaxJointJerk
  (libfranka include/franka/rate_limiting.h), so a waypoint never trips 13, 14 or 15;
* every waypoint is then a q_c of the joint-position generator: judged by the same rows
  (12, 14, 13, 15), applied and published as q_d / dq_d / ddq_d, the measured side
  watched by the safety controller as in any joint motion;
* a target outside the joint range is judged at arrival as row 12
  (joint_motion_generator_position_limits_violation); a non-finite one is refused as 12
  (fci/arrival.py), like any q_c;
* the robot's generator answers every cycle itself: no cycle of an asynchronous motion is
  lost and the sparse targets never make communication_constraints_violation;
* ``motion_generation_finished`` (pylibfranka's ``stop_control()`` sends it with an
  all-zero target, which is not a target) brakes to rest inside the same limits; the
  Move then ends with kSuccess, the arm held at q_d.
"""

from __future__ import annotations

import numpy as np

from .cycle_input import CycleInput
from .engine import MotionLimitEngine
from .errors import Error
from .log_limit import CycleLogLimit
from .reference import JointReference
from .tables import DELTA_T, JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable

#: The share of kMaxJointAcceleration / kMaxJointJerk the profile uses (the rest absorbs
#: float32 rounding of the published references and keeps a waypoint off the threshold).
LIMIT_SHARE = 0.9
#: The braking deceleration the velocity goal plans with, as a share of the acceleration
#: limit: the velocity lags its goal by a_b T, which the other half absorbs.
BRAKING_SHARE = 0.5
#: Time constant of the velocity following its goal [s].
VELOCITY_TIME_CONSTANT = 0.01
#: Near the target the velocity goal is e / (4 T): with the velocity lag T, critically damped.
POSITION_TIME_CONSTANT = 4 * VELOCITY_TIME_CONSTANT
#: Below this speed on every joint a braking generator is at rest and the motion ends [rad/s].
REST_SPEED = 1e-3
#: Kept between the profile's velocity caps and the robot's envelope [rad/s].
VELOCITY_MARGIN = 0.01


def refusal(maximum_velocity) -> str | None:
    """Why a Move's ``maximum_velocity`` cannot configure the generator, or None.

    Seven finite values >= 0 [rad/s] are accepted; values above the robot's nameplate
    velocity are capped by the generator's envelope (libfranka sends the first seven of
    the user's vector; pylibfranka refuses a shorter one client-side).
    """
    v = np.asarray(maximum_velocity if maximum_velocity is not None else (), dtype=float)
    if v.shape != (7,):
        return f"maximum_velocity must hold 7 values, got {v.shape}"
    if not np.all(np.isfinite(v)) or np.any(v < 0):
        return f"maximum_velocity must be 7 finite values >= 0 rad/s, got {v.tolist()}"
    if not np.any(v > 0):
        return "maximum_velocity is zero on every joint: the generator could not move"
    return None


class AsyncPositionGenerator:
    """The asynchronous generator of n robots: targets, caps, and one waypoint per cycle.

    Args:
        n: robots. table: their limits. reference: the joint reference (read; the
            waypoints are recorded by the joint generators). engine: the judge (targets
            outside the joint range).
    """

    def __init__(
        self, n: int, table: RobotTable, reference: JointReference, engine: MotionLimitEngine
    ) -> None:
        self.n = n
        self.table = table
        self.reference = reference
        self.engine = engine
        #: (n,) robots whose running motion is asynchronous
        self.active = np.zeros(n, dtype=bool)
        #: how many (the cycle's fast path skips everything at 0)
        self.count = 0
        #: (n, 7) the newest target (the start pose until one arrives)
        self.target = np.zeros((n, 7))
        #: (n, 7) the per-joint velocity cap the Move configured [rad/s]
        self.vmax = np.zeros((n, 7))
        #: (n,) motion_generation_finished arrived: braking to rest
        self.stopping = np.zeros(n, dtype=bool)
        t = table
        self._a_max = LIMIT_SHARE * t.ddq_max
        self._j_step = LIMIT_SHARE * t.dddq_max * DELTA_T
        self._a_brake = BRAKING_SHARE * t.ddq_max
        # The stopping-distance band: the robot's envelope law with half its deceleration
        # (no deceleration: the joint range itself, at a_b), so following the band asks at
        # most that deceleration and the lag stays inside the robot's envelope.
        decel = t.ddq_decel if t.ddq_decel is not None else self._a_brake
        self._a_band = 0.5 * np.minimum(decel, t.ddq_max)
        self._offset = t.dq_offset if t.dq_offset is not None else np.zeros(7)
        self._v_band = t.dq_max
        self._shift = JOINT_VELOCITY_LIMIT_TOLERANCE + VELOCITY_MARGIN
        self._two_a_brake = 2.0 * self._a_brake
        # The band's constants for [upper | -lower] side by side (the lower bound is the
        # upper one's law on the mirrored range, as fci/tables.py computes the envelope).
        self._mirror = np.concatenate((np.ones(7), -np.ones(7)))
        self._bound = np.concatenate((t.q_upper, -t.q_lower))
        self._two_a_band = np.concatenate([2.0 * self._a_band] * 2)
        self._offset2 = np.concatenate([self._offset] * 2)
        self._v_band2 = np.concatenate([self._v_band] * 2)

    # -- the motion ---------------------------------------------------------------------------

    def start(self, i: int, q: np.ndarray, maximum_velocity) -> None:
        """Robot i starts an asynchronous motion at rest at ``q`` (holding it until a target)."""
        self.active[i] = True
        self.count = int(np.count_nonzero(self.active))
        self.target[i] = q
        self.stopping[i] = False
        caps = np.asarray(maximum_velocity, dtype=float)
        self.vmax[i] = np.minimum(caps, self._v_band - self._shift)

    def end(self, i: int) -> None:
        """Robot i's motion ended (however)."""
        self.active[i] = False
        self.count = int(np.count_nonzero(self.active))
        self.stopping[i] = False

    # -- datagrams ----------------------------------------------------------------------------

    def receive(
        self,
        commands: np.ndarray,
        rows: np.ndarray,
        published: np.ndarray,
        motion_first_id: np.ndarray,
        cycle: CycleInput,
        warnings: CycleLogLimit,
    ) -> None:
        """The datagrams of asynchronous robots (``rows``): new targets, or the finish.

        A datagram echoing any state of the running motion counts (the client sends a
        target when it has one, stamped with the last state it read); one echoing an id
        never published answers nothing and is dropped. A non-finite target is refused
        (12, fci/arrival.py's rule for q_c); one outside the joint range is judged as 12.
        """
        ids = commands["message_id"]
        ok = rows & (ids <= published) & (ids >= motion_first_id)
        for i in np.flatnonzero(rows & ~ok).tolist():
            warnings.warning(
                int(published[i]),
                ("unanswerable", i),
                "robot %d: asynchronous target with message_id %d answers no state of the "
                "running motion (last published %d); dropped",
                i,
                int(ids[i]),
                int(published[i]),
            )
        finish = ok & commands["motion_generation_finished"].astype(bool)
        self.stopping |= finish
        targets = ok & ~finish & ~self.stopping
        if not np.count_nonzero(targets):
            return
        q_c = commands["q_c"]
        finite = np.isfinite(q_c).all(axis=1)
        refused = targets & ~finite
        for i in np.flatnonzero(refused).tolist():
            warnings.warning(
                int(published[i]),
                ("non-finite", i),
                "robot %d: non-finite value in the asynchronous target q_c; target refused",
                i,
            )
        cycle.refused |= refused
        targets &= finite
        t = self.table
        outside = targets & ~((q_c >= t.q_lower) & (q_c <= t.q_upper)).all(axis=1)
        if np.count_nonzero(outside):
            code = int(Error.joint_motion_generator_position_limits_violation)
            error = np.where(outside, code, -1)
            self.engine.judge(error, outside, lambda i: self._describe_outside(i, q_c[i]))
            targets &= self.engine.live(~outside)
        if np.count_nonzero(targets):
            np.copyto(self.target, q_c, where=targets[:, None])

    def _describe_outside(self, i: int, q: np.ndarray) -> str:
        t = self.table
        j = int(np.argmax(np.maximum(t.q_lower - q, q - t.q_upper)))
        return (
            f"asynchronous target joint {j + 1} = {q[j]:.4f} rad outside "
            f"[{t.q_lower[j]:.4f}, {t.q_upper[j]:.4f}]"
        )

    # -- the cycle ----------------------------------------------------------------------------

    def generate(self, cycle: CycleInput, answered: np.ndarray) -> None:
        """This cycle's waypoint of every live asynchronous robot, handed to the joint
        generators as its q_c (``cycle.q_c``, ``cycle.have``); the cycle is answered
        (``answered``); a braking robot at rest finishes its motion (``cycle.finish``)."""
        rows = self.engine.live(self.active)
        k = np.count_nonzero(rows)
        if not k:
            return
        ref = self.reference
        every = k == self.n  # (the socket server's one robot): views, no gathers
        pick = slice(None) if every else rows
        q, v, a = ref.q[pick], ref.dq[pick], ref.ddq[pick]
        e = self.target[pick] - q
        stopping = self.stopping[pick]
        braking = np.count_nonzero(stopping)
        if braking:
            e[stopping] = 0.0
        distance = np.abs(e)
        magnitude = np.sqrt(distance * self._two_a_brake)
        np.minimum(magnitude, distance * (1.0 / POSITION_TIME_CONSTANT), out=magnitude)
        np.minimum(magnitude, self.vmax[pick], out=magnitude)
        goal = np.copysign(magnitude, e, out=magnitude)
        band = self._band(q)  # [upper | -lower]
        np.minimum(goal, band[:, :7], out=goal)
        np.negative(band[:, 7:], out=band[:, 7:])
        np.maximum(goal, band[:, 7:], out=goal)
        # The velocity follows the goal (time constant T): acceleration and jerk capped.
        accel = goal - v
        accel *= 1.0 / VELOCITY_TIME_CONSTANT
        np.minimum(accel, self._a_max, out=accel)
        np.maximum(accel, -self._a_max, out=accel)
        np.minimum(accel, a + self._j_step, out=accel)
        np.maximum(accel, a - self._j_step, out=accel)
        q_new = accel * DELTA_T
        q_new += v
        q_new *= DELTA_T
        q_new += q
        if every:
            cycle.q_c[...] = q_new
        else:
            cycle.q_c[rows] = q_new
        cycle.have |= rows
        answered |= rows
        if braking:
            at_rest = stopping & (np.abs(v) < REST_SPEED).all(axis=1)
            if np.count_nonzero(at_rest):
                done = np.zeros(self.n, dtype=bool)
                done[np.flatnonzero(rows)[at_rest]] = True
                cycle.finish |= done

    def _band(self, q: np.ndarray) -> np.ndarray:
        """(k, 14) [upper | -lower] velocity caps at q: the envelope's law at half its
        deceleration, less the tolerance and the margin (inside the robot's envelope,
        docs/limits.md §4)."""
        r = np.concatenate((q, q), axis=1)
        r *= self._mirror
        np.subtract(self._bound, r, out=r)  # the distance to each stop
        r *= self._two_a_band
        np.maximum(r, 0.0, out=r)
        np.sqrt(r, out=r)
        r -= self._offset2
        np.maximum(r, 0.0, out=r)
        np.minimum(r, self._v_band2, out=r)
        r -= self._shift
        return r
