"""The info entries of the env: the robot's error bits as names, one arm's row of a batch."""

from __future__ import annotations

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
    for i in np.flatnonzero(bits.any(axis=1)).tolist():
        out[i] = error_names(bits[i])
    return out


def mode_names(modes: np.ndarray) -> np.ndarray:
    """RobotMode names per arm ("kMove", "kReflex", ...)."""
    return objects([MODE_NAMES[m] for m in modes.tolist()])


def info_row(info: dict[str, np.ndarray], i: int) -> dict:
    """One arm's info as a single env reports it (Python scalars and tuples); the vector
    layout's ``_key`` masks and nested vector infos (``final_info``) are left out."""
    return {
        key: (value[i] if value.dtype == object or value.ndim > 1 else value[i].item())
        for key, value in info.items()
        if not key.startswith("_") and isinstance(value, np.ndarray)
    }


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
