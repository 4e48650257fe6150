"""The motion-limit engine's judge: violations logged, verdicts returned to the controller.

docs/fci-behaviour.md "Motion limits and discontinuities": the generators (``joint_generators``,
``cartesian``) and the safety controller (``safety_controller``) run the rule
functions of ``limits`` and hand every tripped error to :meth:`MotionLimitEngine.judge`.
A violation is logged always (once per class per motion, ``violations``); with
enforcement on it becomes a :class:`Verdict` — abort robot i's motion latching these
bits — which the controller applies (its reflex) once the generator returns. Until
then ``aborted`` marks those robots, so that the generator does not apply or record
what they commanded.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .config import ControllerConfig
from .cycle_input import CycleInput
from .errors import Error
from .limits import NO_ERROR
from .modes import Modes
from .violations import ViolationLog, latched_bits


class Verdict(NamedTuple):
    """Abort robot ``robot``'s motion, latching the error bits ``bits`` (the reflex)."""

    robot: int
    bits: list[int]


class MotionLimitEngine:
    """Logs what the rules found and turns enforced violations into verdicts."""

    def __init__(self, n: int, modes: Modes, config: ControllerConfig) -> None:
        self.modes = modes
        self.config = config
        #: violations logged (once per class per motion) and seen
        self.violations = ViolationLog(n)
        #: (n,) robots a verdict not yet applied aborts
        self.aborted = np.zeros(n, dtype=bool)
        self._verdicts: list[Verdict] = []  # (their robots are the ones set in ``aborted``)

    def live(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` without the robots a pending verdict aborts."""
        if not self._verdicts:
            return rows
        return rows & ~self.aborted

    def judge(self, error: np.ndarray, rows: np.ndarray, describe, extra=None) -> None:
        """Log every violation (``error`` >= 0) in ``rows`` of robots in motion; with
        enforcement on, a verdict aborts each such robot.

        ``describe(i)`` names robot i's violation (a ``Violation`` or a string), called
        for a violating robot only; ``extra`` maps a robot to further bits its one abort
        latches (29 with 30)."""
        bad = rows & (error >= 0) & self.modes.in_motion & ~self.aborted
        if not np.count_nonzero(bad):
            return
        enforce = self.config.enforce_motion_limits
        for i in np.flatnonzero(bad).tolist():
            e = int(error[i])
            described = describe(i)
            message = described.message() if hasattr(described, "message") else str(described)
            self.violations.report(i, e, message, enforce)
            bits = latched_bits(e)
            if extra and i in extra:
                for b in extra[i]:
                    self.violations.report(i, b, message, enforce)
                bits = bits + extra[i]
            if enforce:
                self.abort(i, bits)

    def report(self, i: int, error: int, message: str, enforce: bool) -> None:
        """Log one violation of robot i (the safety controller's and the communication
        bound's, which carry their own enforcement switch)."""
        self.violations.report(i, error, message, enforce)

    def abort(self, i: int, bits: list[int]) -> None:
        """A verdict: abort robot i's motion latching ``bits``."""
        self.aborted[i] = True
        self._verdicts.append(Verdict(i, bits))

    def take_verdicts(self) -> list[Verdict]:
        """The verdicts since the last call, for the controller to apply (in order)."""
        verdicts, self._verdicts = self._verdicts, []
        if verdicts:
            self.aborted[...] = False
        return verdicts

    def judge_non_finite(self, cycle: CycleInput) -> None:
        """docs/fci-behaviour.md "What is checked, and what it latches": a non-finite command is
        refused whatever the enforcement, and reported as
        the limits violation of the field it arrived in (12 q_c, 13 dq_c, 34 tau_J_d, also
        beside a finite generator command under an external controller; Cartesian: 31
        for a pose that is no homogeneous transformation, NaN included, 18 for a
        non-finite twist, 17 for a non-finite elbow)."""
        m = self.modes
        refused = cycle.refused & m.in_motion
        error = np.full(len(refused), NO_ERROR)
        error[refused & m.external] = Error.tau_j_range_violation
        error[refused & m.joint_velocity] = Error.joint_motion_generator_velocity_limits_violation
        error[refused & m.joint_position] = Error.joint_motion_generator_position_limits_violation
        error[refused & m.cartesian_velocity] = (
            Error.cartesian_motion_generator_velocity_limits_violation
        )
        error[refused & m.cartesian_position] = (
            Error.cartesian_position_motion_generator_invalid_frame
        )
        elbow = Error.cartesian_motion_generator_elbow_limit_violation
        error[cycle.refused_elbow & refused] = elbow
        error[cycle.refused_torque & refused] = Error.tau_j_range_violation
        cycle.refused_elbow[...] = False
        cycle.refused_torque[...] = False

        def describe(i: int) -> str:
            if error[i] == Error.cartesian_position_motion_generator_invalid_frame:
                return "O_T_EE_c is not a homogeneous transformation (refused)"
            return "non-finite commanded value (refused)"

        self.judge(error, refused, describe)
        cycle.refused[...] = False
