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
        key: (value[i] if value.dtype == object else value[i].item())
        for key, value in info.items()
        if not key.startswith("_") and isinstance(value, np.ndarray)
    }
