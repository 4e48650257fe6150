"""The loader of the C extensions for the 1 kHz hot path (no rule lives here).

Two kinds. **Kernels** (``native.load``) replace one whole rule that still has a numpy
text: the same signature as the numpy function it stands in for, in that function's
layer (``sim/_ik.c``: the IK solve; ``sim/_dynamics.c``: the Jacobian at a point;
``sim/_rows.c``: the loops copying every robot's MjData rows, no rule;
``envs/_client_filters.c``: the libfranka client's filters), every constant passed in
from the tables, never fused with the code of another layer; the numpy function stays
the rule and a test holds the kernel to it.
**Required extensions** (``native.require``) hold rules whose only text is C (issue 38:
``fci/limits/_joint.c``: the joint-position and joint-velocity generators' precedence
tables, the velocity envelope's law, the safety controller's errors 3 and 4 and the
torque interface's 34 and 32; ``fci/_contact.c``: the contact estimate, the wrench at
K and the collision levels): no numpy path, no switch (docs/architecture.md, "One
implementation per rule", says which rules are where and why).
This package holds what they share: the switch, the loaders and the C headers
``_arrays.h`` (checked array arguments, float64 and one-byte flags), ``_rotation.h``,
``_solve6.h`` and ``_ik_core.h``.

They are built at install time (``pip install .`` compiles every
``franka_sim_gym/<layer>/_<name>.c``; setup.py). Where no C compiler is available the
install fails (the required extension cannot be built); an optional kernel that is
absent leaves its caller on its numpy path. ``FRANKA_SIM_GYM_NATIVE=0`` in the
environment turns the kernels off (read once, at import): the reference paths, for
comparison and debugging. It does not touch the required extensions' rules.
"""

from __future__ import annotations

import functools
import importlib
import logging
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


log = logging.getLogger("franka_sim_gym.native")


@functools.cache
def load(name: str) -> ModuleType | None:
    """The kernel module ``franka_sim_gym.<name>`` (e.g. ``"sim._ik"``), or None
    when it was not built, the kernels are turned off, or it was built for another cycle
    (a stale build).

    Not built (no such module) is silent: the numpy path is the documented fallback. A
    module that is there but does not import (a broken or foreign build: an undefined
    symbol, another Python's ABI) or is stale is logged once, as a warning saying why,
    and its numpy path taken.
    """
    if not ENABLED:
        return None
    module_name = f"franka_sim_gym.{name}"
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name != module_name:  # the kernel is there; something it imports is not
            log.warning("C kernel %s not loaded (numpy path taken): %s", name, exc)
        return None
    except ImportError as exc:
        log.warning("C kernel %s not loaded (numpy path taken): %s", name, exc)
        return None
    why = _stale(module)
    if why:
        log.warning("C kernel %s not loaded (numpy path taken): %s: reinstall", name, why)
        return None
    return module


def _stale(module: ModuleType, *functions: str) -> str | None:
    """Why ``module`` is a stale build (built for another cycle, or from an older source
    without one of ``functions``), or None."""
    built = getattr(module, "DELTA_T", None)
    if built != CYCLE:
        return f"built for a cycle of {built!r} s, not {CYCLE!r} s (a stale build)"
    missing = [f for f in functions if not callable(getattr(module, f, None))]
    if missing:
        return f"it has no {', '.join(missing)} (a stale build from an older source)"
    return None


@functools.cache
def require(name: str, *functions: str) -> ModuleType:
    """The extension ``franka_sim_gym.<name>`` holding rules whose only text is C (issue
    38: one text per rule), with each of ``functions``: imported whatever
    ``FRANKA_SIM_GYM_NATIVE`` says (the switch chooses between two texts; these rules
    have one). Missing, broken or stale (built for another cycle, or from an older source
    without one of ``functions``), it is an ImportError at import saying so and how to
    build it, never an AttributeError inside the cycle.
    """
    module_name = f"franka_sim_gym.{name}"
    build = (
        "the rules in it have no other text: install franka-sim-gym where a C compiler and "
        "Python's headers are available (`pip install -e .` or `make test` builds it; setup.py)"
    )
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ImportError(f"{module_name} does not import ({exc}); {build}") from exc
    why = _stale(module, *functions)
    if why:
        raise ImportError(f"{module_name}: {why}; {build}")
    return module


#: The kernel modules setup.py builds (one per ``<layer>/_<name>.c``) that the switch
#: chooses against a numpy text.
MODULES = (
    "sim._ik",
    "sim._dynamics",
    "sim._rows",
    "envs._client_filters",
)
#: The extensions holding rules whose only text is C (``require``): always in use.
REQUIRED = ("fci.limits._joint", "fci._contact")


def loaded() -> dict[str, bool]:
    """Which switchable kernel modules are in use (for benchmarks and bug reports)."""
    return {name: load(name) is not None for name in MODULES}


def describe() -> str:
    """One line for a benchmark's header: which kernels ran (the required extensions
    always do)."""
    state = ", ".join(f"{name} {'on' if on else 'off'}" for name, on in loaded().items())
    switch = "" if ENABLED else " (FRANKA_SIM_GYM_NATIVE=0)"
    return f"C kernels: {state}{switch}; required: {', '.join(REQUIRED)}"


__all__ = ["ENABLED", "MODULES", "REQUIRED", "describe", "load", "loaded", "require"]
