"""Collision detection per SetCollisionBehavior: thresholds, phases, contact and collision.

SetCollisionBehavior (libfranka ``Robot::setCollisionBehavior``, ``robot.h``) gives,
per joint and per Cartesian axis (x, y, z in N; R, P, Y in Nm), a lower and an upper
threshold for two phases of a motion, "acceleration" and "nominal"; the 4-argument
overload sends the same values for both. The robot compares its external-torque
estimate (tau_ext_hat_filtered) with the joint thresholds and its external wrench
(O_F_ext_hat_K) with the Cartesian ones:

* above a lower threshold the component's ``joint_contact`` / ``cartesian_contact``
  reads 1, and 0 again once below it;
* above an upper threshold its ``joint_collision`` / ``cartesian_collision`` latches
  (until AutomaticErrorRecovery) and the motion aborts with ``joint_reflex`` (6) or
  ``cartesian_reflex`` (7).

What the robot takes as its acceleration phase is not published; here a running
motion whose commanded joint acceleration exceeds ``ACCELERATION_PHASE`` on any joint
is in it, any other cycle nominal (a choice, docs/motion-limits.md).

This module holds the thresholds (their defaults, what a payload may carry, each robot's
configured ones). The comparisons, the phase and the flags are the cycle's sensing step,
whose only text is C (fci/contact/_contact.c ``sense``, called by fci/contact/sensing.py).
"""

from __future__ import annotations

import numpy as np

#: The thresholds Franka's own examples set before every motion (libfranka
#: ``examples/examples_common.cpp``, ``setDefaultBehavior``: lower = upper, both
#: phases). Desk's factory thresholds are not published, so these are a choice:
#: the ones most FCI programs run with.
DEFAULT_TORQUE_THRESHOLDS = (20.0, 20.0, 18.0, 18.0, 16.0, 14.0, 12.0)
DEFAULT_FORCE_THRESHOLDS = (20.0, 20.0, 20.0, 25.0, 25.0, 25.0)
#: |ddq_d| above which a motion is in its acceleration phase [rad/s^2] (a choice).
ACCELERATION_PHASE = 0.5

#: The payload's arrays in wire order (fci/wire/request_payloads.py SetCollisionBehaviorRequest).
THRESHOLD_NAMES = (
    "lower_torque_thresholds_acceleration",
    "upper_torque_thresholds_acceleration",
    "lower_torque_thresholds_nominal",
    "upper_torque_thresholds_nominal",
    "lower_force_thresholds_acceleration",
    "upper_force_thresholds_acceleration",
    "lower_force_thresholds_nominal",
    "upper_force_thresholds_nominal",
)


def invalid_thresholds(values: dict[str, np.ndarray]) -> str | None:
    """Why a SetCollisionBehavior payload is refused, or None when it is accepted.

    The robot's accepted range is not published: we refuse what cannot be meant,
    a non-finite or negative threshold, and accept the rest (a lower threshold above
    its upper one included: the collision then comes first).
    """
    for name in THRESHOLD_NAMES:
        v = np.asarray(values[name], dtype=float)
        if not np.all(np.isfinite(v)):
            return f"{name}: non-finite threshold"
        if np.any(v < 0):
            return f"{name}: negative threshold {v.tolist()}"
    return None


def four_argument_form(thresholds) -> dict[str, np.ndarray]:
    """SetCollisionBehavior's payload from libfranka's 4-argument form
    ``(lower_torque, upper_torque, lower_force, upper_force)``: each (7,) or (6,) or a
    scalar for every joint / axis, sent for both phases (libfranka ``robot.h``).

    Raises:
        ValueError: not four entries, a wrong length, or a threshold the robot refuses.
    """
    try:
        lower_torque, upper_torque, lower_force, upper_force = thresholds
        arrays = [
            np.broadcast_to(np.asarray(v, dtype=float), (size,)).copy()
            for v, size in zip(
                (lower_torque, upper_torque, lower_force, upper_force), (7, 7, 6, 6), strict=True
            )
        ]
    except (TypeError, ValueError) as exc:
        raise ValueError(
            "collision thresholds must be (lower_torque, upper_torque, lower_force, "
            f"upper_force): 7, 7, 6 and 6 values or scalars, got {thresholds!r}"
        ) from exc
    t_lo, t_up, f_lo, f_up = arrays
    phases = (t_lo, t_up, t_lo, t_up, f_lo, f_up, f_lo, f_up)
    values = dict(zip(THRESHOLD_NAMES, phases, strict=True))
    why = invalid_thresholds(values)
    if why is not None:
        raise ValueError(f"collision thresholds refused: {why}")
    return values


class CollisionBehavior:
    """The configured thresholds of n robots: (n, 2, 7) torques and (n, 2, 6) forces,
    phase 0 = acceleration, 1 = nominal; all four are views of :attr:`thresholds`."""

    def __init__(self, n: int) -> None:
        #: (n, 2, 26) per phase: lower torque (7), upper torque (7), lower force (6),
        #: upper force (6), side by side (one array for the C text, fci/contact/_contact.c)
        self.thresholds = np.empty((n, 2, 26))
        self.lower_torque = self.thresholds[:, :, 0:7]
        self.upper_torque = self.thresholds[:, :, 7:14]
        self.lower_force = self.thresholds[:, :, 14:20]
        self.upper_force = self.thresholds[:, :, 20:26]
        for i in range(n):
            self.reset(i)

    def reset(self, i: int) -> None:
        """Robot i back to the defaults (a new connection, an env reset)."""
        self.lower_torque[i] = self.upper_torque[i] = DEFAULT_TORQUE_THRESHOLDS
        self.lower_force[i] = self.upper_force[i] = DEFAULT_FORCE_THRESHOLDS

    def configure(self, i: int, values: dict[str, np.ndarray]) -> None:
        """Store robot i's thresholds (validated by :func:`invalid_thresholds`)."""
        for phase, suffix in enumerate(("acceleration", "nominal")):
            self.lower_torque[i, phase] = values[f"lower_torque_thresholds_{suffix}"]
            self.upper_torque[i, phase] = values[f"upper_torque_thresholds_{suffix}"]
            self.lower_force[i, phase] = values[f"lower_force_thresholds_{suffix}"]
            self.upper_force[i, phase] = values[f"upper_force_thresholds_{suffix}"]
