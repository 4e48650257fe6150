"""The info entries of the env: the robot's error bits as names, one arm's row of a batch."""

from __future__ import annotations

import copy

import numpy as np

from ..fci.errors import error_names
from ..fci.wire import RobotMode

#: RobotMode values by number, as info["robot_mode"] names them
MODE_NAMES = {int(m): m.name for m in RobotMode}


def objects(values: list) -> np.ndarray:
    """A 1-D object array of ``values`` (numpy would make tuples a second axis)."""
    out = np.empty(len(values), dtype=object)
    out[:] = values
    return out


def names(bits: np.ndarray) -> np.ndarray:
    """Per row of (n, 41) error bits: the tuple of the robot's error names."""
    out = np.empty(len(bits), dtype=object)
    out.fill(())
    if bits.any():  # (most steps: no error anywhere)
        for i in np.flatnonzero(bits.any(axis=1)).tolist():
            out[i] = error_names(bits[i])
    return out


def mode_names(modes: np.ndarray) -> np.ndarray:
    """RobotMode names per arm ("kMove", "kReflex", ...)."""
    return objects([MODE_NAMES[m] for m in modes.tolist()])


#: what copy.deepcopy returns as it is
ATOMIC = frozenset({bool, int, float, str, type(None)})


def immutable(value) -> bool:
    """True for a value copy.deepcopy returns unchanged: a Python scalar, a string, None
    or a tuple of them (the error-name tuples)."""
    kind = type(value)
    return kind in ATOMIC or (kind is tuple and all(immutable(x) for x in value))


class InfoRow(dict):
    """One arm's info: a ``dict`` whose deep copy is the same as a dict's, made faster.

    Learners copy infos per sample: SB3's ``HerReplayBuffer(copy_info_dict=True)`` (the
    shipped rl-zoo3 file's buffer, docs/training.md) deep-copies the stored info of every
    relabelled transition at every gradient step. A dict's deep copy visits every key and
    value; most of this info's are immutable, which ``copy.deepcopy`` returns as they are,
    so this copy takes them over at once and deep-copies the rest (the contact arrays and
    whatever a wrapper added, e.g. SB3's ``terminal_observation``): the same result in
    about a third of the time (benchmarks/RESULTS.md).
    """

    def __deepcopy__(self, memo: dict) -> InfoRow:
        out = InfoRow(self)
        memo[id(self)] = out
        for key, value in self.items():
            if not immutable(value):
                out[key] = copy.deepcopy(value, memo)
        return out


def info_row(info: dict[str, np.ndarray], i: int) -> InfoRow:
    """One arm's info as a single env reports it (Python scalars and tuples); the vector
    layout's ``_key`` masks and nested vector infos (``final_info``) are left out."""
    return InfoRow(
        (key, value[i] if value.dtype == object or value.ndim > 1 else value[i].item())
        for key, value in info.items()
        if not key.startswith("_") and isinstance(value, np.ndarray)
    )


def step_info(
    states: np.ndarray,
    lost: np.ndarray,
    longest_lost: np.ndarray,
    violations: np.ndarray,
    cycles: np.ndarray,
    is_success: np.ndarray,
    penalty: np.ndarray,
) -> dict[str, np.ndarray]:
    """The info of n arms after a step (or a reset), from their published states."""
    return {
        "errors": names(states["errors"]),
        "reflex_reason": names(states["reflex_reason"]),
        "robot_mode": mode_names(states["robot_mode"]),
        "control_command_success_rate": states["control_command_success_rate"].astype(np.float64),
        "lost_cycles": lost,
        "longest_lost_run": longest_lost.copy(),
        "violations": names(violations),
        "cycles": cycles.copy(),
        "is_success": is_success,
        "reflex_penalty": penalty,
        # What the robot senses of contact (docs/robot-state.md, the contact group).
        "joint_contact": states["joint_contact"] > 0,
        "cartesian_contact": states["cartesian_contact"] > 0,
        "O_F_ext_hat_K": states["O_F_ext_hat_K"].astype(np.float64),
    }
