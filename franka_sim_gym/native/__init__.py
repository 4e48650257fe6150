"""Optional C kernels for the 1 kHz hot path, each a fused copy of numpy reference code.

At one arm, a cycle's cost is the number of numpy calls, not their arithmetic (each
costs 0.3-1 us on arrays of 7 values). The kernels here fuse a hot function's calls
into one C call. Each has a numpy reference, which stays the rule (the one the docs
and the seed describe); tests hold the kernel to it: bit for bit where the reference
is elementwise arithmetic, and to the same verdicts everywhere.

The kernels are built at install time (``pip install .`` compiles
``franka_sim_gym/native/_*.c``; setup.py). Where no C compiler was available they
are absent and every caller takes its numpy path. ``FRANKA_SIM_GYM_NATIVE=0`` in the
environment turns them off (read once, at import): the reference paths, for
comparison and debugging.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

#: False when FRANKA_SIM_GYM_NATIVE=0 (or "false", "no", "off"): numpy paths only.
ENABLED = os.environ.get("FRANKA_SIM_GYM_NATIVE", "1").strip().lower() not in {
    "0",
    "false",
    "no",
    "off",
}


#: The cycle the kernels difference over: fci/tables.py DELTA_T (libfranka's kDeltaT).
#: Repeated here, not imported, so that this package depends on nothing of the others.
CYCLE = 1e-3


def load(name: str) -> ModuleType | None:
    """The kernel module ``franka_sim_gym.native.<name>``, or None when it was not built,
    the kernels are turned off, or it was built for another cycle (a stale build)."""
    if not ENABLED:
        return None
    try:
        module = importlib.import_module(f"{__name__}.{name}")
    except ImportError:
        return None
    return module if getattr(module, "DELTA_T", None) == CYCLE else None


#: The kernel modules setup.py builds (one per ``_<name>.c``).
MODULES = ("_joint", "_cartesian", "_client")


def loaded() -> dict[str, bool]:
    """Which kernel modules are in use (for benchmarks and bug reports)."""
    return {name: load(name) is not None for name in MODULES}


def describe() -> str:
    """One line for a benchmark's header: which kernels ran."""
    state = ", ".join(f"{name[1:]} {'on' if on else 'off'}" for name, on in loaded().items())
    switch = "" if ENABLED else " (FRANKA_SIM_GYM_NATIVE=0)"
    return f"C kernels: {state}{switch}"


__all__ = ["ENABLED", "MODULES", "describe", "load", "loaded"]
