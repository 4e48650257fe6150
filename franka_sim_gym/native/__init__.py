"""The loader of the optional C kernels for the 1 kHz hot path (no rule lives here).

At one arm, a cycle's cost is the number of numpy calls, not their arithmetic (each
costs 0.3-1 us on arrays of 7 values). A kernel fuses a hot function's calls into one
C call; it sits next to the numpy code it copies, in that code's layer
(``fci/_joint_rules.c``, ``fci/_cartesian_rules.c``, ``sim/_ik.c``,
``envs/_client_filters.c``), and that numpy code stays the rule (the one the docs and
the seed describe); tests hold the kernel to it: bit for bit where the reference is
elementwise arithmetic, and to the same verdicts everywhere. This package holds what
they share: the switch, the loader and the C headers ``_arrays.h``, ``_rotation.h`` and
``_ik_core.h`` (the IK solve, for ``sim/_ik.c`` and the Cartesian rules' plain cycle).

The kernels are built at install time (``pip install .`` compiles every
``franka_sim_gym/<layer>/_<name>.c``; setup.py). Where no C compiler was available
they are absent and every caller takes its numpy path. ``FRANKA_SIM_GYM_NATIVE=0`` in the
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
    """The kernel module ``franka_sim_gym.<name>`` (e.g. ``"fci._joint_rules"``), or None
    when it was not built, the kernels are turned off, or it was built for another cycle
    (a stale build)."""
    if not ENABLED:
        return None
    try:
        module = importlib.import_module(f"franka_sim_gym.{name}")
    except ImportError:
        return None
    return module if getattr(module, "DELTA_T", None) == CYCLE else None


#: The kernel modules setup.py builds (one per ``<layer>/_<name>.c``).
MODULES = ("fci._joint_rules", "fci._cartesian_rules", "sim._ik", "envs._client_filters")


def loaded() -> dict[str, bool]:
    """Which kernel modules are in use (for benchmarks and bug reports)."""
    return {name: load(name) is not None for name in MODULES}


def describe() -> str:
    """One line for a benchmark's header: which kernels ran."""
    state = ", ".join(f"{name} {'on' if on else 'off'}" for name, on in loaded().items())
    switch = "" if ENABLED else " (FRANKA_SIM_GYM_NATIVE=0)"
    return f"C kernels: {state}{switch}"


__all__ = ["ENABLED", "MODULES", "describe", "load", "loaded"]
