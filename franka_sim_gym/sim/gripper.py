"""The Franka Hand's commands (:class:`HandModel`) and its kinematic backend (:class:`FrankaHand`).

:class:`HandModel` is what the gripper server drives, whatever moves the
fingers: it validates Homing/Move/Grasp/Stop, keeps the running action and
the (action id, outcome) pairs the server answers, and the broadcast fields.
Two backends implement it: :class:`FrankaHand` here (kinematic, the default)
and :class:`~franka_sim_gym.sim.physics_hand.PhysicsHand` (MuJoCo fingers on a
PD servo, ``--gripper-physics``).

Behaviour and constants: docs/fci-behaviour.md "Gripper fidelity", docs/gripper.md
and docs/wire-protocol.md §10.2:

* the stroke is 0 .. ``MAX_WIDTH`` = 0.08 m (the real hand's 8 cm);
* ``move`` and ``grasp`` change the width at the commanded speed over time
  (a snapped width would hide the motion's duration);
* an optional rigid virtual object ``object_width`` wide sits between the
  fingers (``--gripper-object-width``): a closing motion stalls there, opening
  is never blocked;
* a grasp closes until the fingers stall (on the object, or on each other at
  0 m) and then applies libfranka's documented test (include/franka/gripper.h)
  ``width - epsilon_inner < d < width + epsilon_outer`` to the stall width d,
  so a grasp of thin air fails and ``grasp(0.0)`` on nothing succeeds;
* ``stop`` halts the fingers where they are (the real hand halts in place).

The kinematic backend does not model force: the commanded force is validated
but never applied (docs/gripper.md "Two backends, one protocol" (grasp force); the physics backend
applies it). It is deterministic: time advances only through :meth:`FrankaHand.step`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

__all__ = ["MAX_WIDTH", "HOMING_SPEED", "TEMPERATURE_C", "Outcome", "HandModel", "FrankaHand"]

#: docs/fci-behaviour.md "Gripper fidelity": max_width is the hand's 0.08 m stroke.
MAX_WIDTH = 0.08
#: Homing speed [m/s]: libfranka's homing takes no speed and the real one is not
#: documented; this value is our choice.
HOMING_SPEED = 0.05
#: docs/fci-behaviour.md "Gripper fidelity": temperature is a constant 30 °C.
TEMPERATURE_C = 30


class Outcome(Enum):
    """How an action ended; maps to the gripper status of docs/wire-protocol.md §10.2."""

    SUCCESS = 0  # kSuccess: libfranka returns True
    UNSUCCESSFUL = 2  # kUnsuccessful: libfranka returns False
    ABORTED = 3  # kAborted: libfranka raises "Command aborted!"


@dataclass
class _Action:
    id: int
    kind: str  # "homing" | "move" | "grasp"
    target: float
    speed: float
    grasp_band: tuple[float, float] | None = None  # open interval (lo, hi) for d
    force: float | None = None  # grasp force [N]


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


class HandModel:
    """The commands and broadcast state of one Franka Hand; a backend moves the fingers.

    Subclasses provide ``width`` (the measured opening [m]) and :meth:`step`,
    and may react to an action starting (:meth:`_begin`) and to Stop
    (:meth:`_halt`).

    Args:
        object_width: width [m] of the rigid virtual object between the
            fingers, or None for an empty hand (the shipped scene has nothing
            graspable).
    """

    width: float

    def __init__(self, object_width: float | None = None) -> None:
        if object_width is not None and not (
            _finite(object_width) and 0.0 <= object_width <= MAX_WIDTH
        ):
            raise ValueError(f"object width {object_width} outside the 0-{MAX_WIDTH} m stroke")
        self.object_width = object_width
        self.max_width = MAX_WIDTH
        self.is_grasped = False
        self._action: _Action | None = None
        self._next_id = 1
        self._finished: list[tuple[int, Outcome]] = []
        self.outcome: Outcome | None = None  # outcome of the most recent action

    # -- commands ---------------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """True while a homing, move or grasp is running."""
        return self._action is not None

    @property
    def action_id(self) -> int | None:
        """Id of the running action, or None."""
        return None if self._action is None else self._action.id

    def homing(self) -> int:
        """Open to ``max_width`` (homing re-estimates max_width; here it is constant)."""
        return self._start("homing", self.max_width, HOMING_SPEED)

    def move(self, width: float, speed: float) -> int:
        """Drive to ``width`` at ``speed``; returns the action id.

        Raises ValueError for a width outside the stroke or a non-finite or
        non-positive speed (the server answers kFail: docs/fci-behaviour.md "Command coverage").
        """
        self._check(width, speed)
        return self._start("move", float(width), float(speed))

    def grasp(
        self,
        width: float,
        speed: float,
        force: float,
        epsilon_inner: float = 0.005,
        epsilon_outer: float = 0.005,
    ) -> int:
        """Close at ``speed`` until the fingers stall, then test the stall width.

        The defaults 0.005 m are libfranka's (docs/wire-protocol.md §10.2).
        ``force`` [N] must be finite and non-negative; what a backend does with
        it is its own (the kinematic one ignores it, the physics one limits the
        finger force to it).
        """
        self._check(width, speed)
        if (
            not _finite(force, epsilon_inner, epsilon_outer)
            or min(force, epsilon_inner, epsilon_outer) < 0
        ):
            raise ValueError("force and epsilons must be finite and non-negative")
        band = (width - epsilon_inner, width + epsilon_outer)
        return self._start("grasp", 0.0, float(speed), band, float(force))

    def stop(self) -> None:
        """Halt where the fingers are; a running action ends ABORTED (the real hand halts)."""
        self._halt()
        if self._action is not None:
            self._finish(Outcome.ABORTED)

    def take_finished(self) -> list[tuple[int, Outcome]]:
        """The (action id, outcome) pairs finished since the last call, oldest first."""
        done, self._finished = self._finished, []
        return done

    def step(self, dt: float) -> None:
        """Advance the fingers by ``dt`` seconds (or poll them: backend-specific)."""
        raise NotImplementedError

    # -- internals --------------------------------------------------------------------------

    def _begin(self, action: _Action) -> None:
        """A backend's reaction to a new action (after the previous one was preempted)."""

    def _halt(self) -> None:
        """A backend's reaction to Stop, before the running action is aborted."""

    def _grasped(self, width: float) -> bool:
        """libfranka's test on the stall width d: width - eps_inner < d < width + eps_outer."""
        assert self._action is not None and self._action.grasp_band is not None
        lo, hi = self._action.grasp_band
        return lo < width < hi

    def _check(self, width: float, speed: float) -> None:
        if not (_finite(width) and 0.0 <= width <= self.max_width):
            raise ValueError(f"width {width} outside the 0-{self.max_width} m stroke")
        if not (_finite(speed) and speed > 0):
            raise ValueError(f"speed {speed} must be finite and positive")

    def _start(self, kind: str, target: float, speed: float, band=None, force=None) -> int:
        if self._action is not None:
            # A new command preempts the running one (our choice; not documented).
            self._finish(Outcome.ABORTED)
        self.is_grasped = False  # a new motion releases any grip
        self._action = _Action(self._next_id, kind, target, speed, band, force)
        self._next_id += 1
        self.outcome = None
        self._begin(self._action)
        return self._action.id

    def _finish(self, outcome: Outcome) -> None:
        assert self._action is not None
        self._finished.append((self._action.id, outcome))
        self.outcome = outcome
        self._action = None


class FrankaHand(HandModel):
    """The kinematic Franka Hand: the width moves at the commanded speed, advanced by :meth:`step`.

    Args:
        object_width: width [m] of a rigid object between the fingers, or None
            for an empty hand (the shipped scene has nothing graspable).
        width: initial finger width [m] (fully open by default).
    """

    def __init__(self, object_width: float | None = None, width: float = MAX_WIDTH) -> None:
        super().__init__(object_width)
        self.width = max(float(width), self._floor)

    @property
    def _floor(self) -> float:
        """The narrowest the fingers can get: the object's width, or closed."""
        return 0.0 if self.object_width is None else self.object_width

    # -- time -------------------------------------------------------------------------------

    def step(self, dt: float) -> None:
        """Advance the fingers by ``dt`` seconds."""
        action = self._action
        if action is None or dt <= 0:
            return
        target = max(action.target, self._floor)
        delta = action.speed * dt
        if abs(target - self.width) <= delta:
            self.width = target
        else:
            self.width += math.copysign(delta, target - self.width)
        if self.width != target:
            return
        if action.kind == "grasp":
            # The fingers stalled (on the object, or on each other): libfranka's test.
            self.is_grasped = self._grasped(self.width)
            self._finish(Outcome.SUCCESS if self.is_grasped else Outcome.UNSUCCESSFUL)
        elif target != action.target:
            # A move stalled on the object short of its target. What the real hand
            # answers is not documented; we answer "unsuccessful" (libfranka: False).
            self._finish(Outcome.UNSUCCESSFUL)
        else:
            self._finish(Outcome.SUCCESS)
