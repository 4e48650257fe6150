"""Violation bookkeeping: log always (once per error class per motion), abort only when enforced.

docs/fci-behaviour.md "Checking is always on; aborting is opt-in": every command is validated;
each violation is logged as a warning that says which joint or axis, by how much and
against which limit, once per error class per motion ("(not enforced)" when the
switch is off).
``seen`` keeps every violation (enforced or not) until the way in takes it,
so the Gymnasium env can report what would have tripped with enforcement off.
"""

from __future__ import annotations

import logging

import numpy as np

from .errors import ERROR_COUNT, ERROR_NAMES, Error

log = logging.getLogger("franka_sim_gym.fci")

#: docs/fci-behaviour.md "joint_velocity_violation (3)": a commanded-envelope violation (13)
#: latches the safety controller's 3 with it, in the same abort.
_PAIRED = {
    int(Error.joint_motion_generator_velocity_limits_violation): int(Error.joint_velocity_violation)
}


def latched_bits(error: int) -> list[int]:
    """The error bits one violation latches (13 brings 3 with it)."""
    return [error, _PAIRED[error]] if error in _PAIRED else [error]


class ViolationLog:
    """Per robot: which error classes were logged in this motion, and every violation seen."""

    def __init__(self, n: int) -> None:
        self._logged = np.zeros((n, ERROR_COUNT), dtype=bool)
        #: every violation since the last take(), enforced or not
        self.seen = np.zeros((n, ERROR_COUNT), dtype=bool)

    def begin_motion(self, i: int) -> None:
        self._logged[i] = False

    def report(self, i: int, error: int, message: str, enforced: bool) -> None:
        """Record robot i's violation of ``error``; log it unless this motion already did."""
        for bit in latched_bits(error):
            self.seen[i, bit] = True
        if self._logged[i, error]:
            return
        self._logged[i, error] = True
        suffix = "" if enforced else " (not enforced)"
        if not message.startswith(ERROR_NAMES[error]):
            message = f"{ERROR_NAMES[error]}: {message}"
        log.warning("robot %d: motion limit violated: %s%s", i, message, suffix)

    def take(self) -> np.ndarray:
        """The violations seen since the last call, (n, 41) bool; clears them."""
        seen = self.seen.copy()
        self.seen[...] = False
        return seen
