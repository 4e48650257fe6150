"""The loader of the C extensions of the 1 kHz hot path (no rule lives here).

Every extension holds rules whose only text is C (issue 38: one text per rule, no numpy
twin, no switch): ``fci/_arrival.c`` (which arriving commands a cycle takes, refuses
or counts as lost, and what it keeps of them), ``fci/_frames.c`` (libfranka's
isHomogeneousTransformation on a batch),
``fci/_measured.c`` (the RobotState's measured joint fields, with the sensors' noise),
``fci/_accounting.c`` (the close of a cycle: success-rate window, lost-cycle runs),
``fci/limits/_joint.c`` (the joint and Cartesian generators' precedence tables, the
joint generators' cycle with the q_c and dq_c lost-cycle laws and the reference's
record, the velocity envelope's law, the safety controller's errors 3 and 4, the torque
interface's 34 and 32), ``fci/contact/_contact.c`` (the contact estimate, the wrench at
K, the collision levels), ``sim/_ik.c`` (the IK solve), ``sim/_dynamics.c`` (the
Jacobian at a point), ``sim/_truth.c`` (a reality draw's drive friction and link weights),
``sim/_rotations.c`` (the rotation library, sim/rotations.py's one text),
``envs/_client_filters.c`` (libfranka's client filters), and ``sim/_rows.c`` (no rule:
the copies of every robot's MjData rows). docs/architecture.md, "One implementation per
rule", says which rules are where and why.

They are built at install time (``pip install .`` compiles every
``franka_sim_gym/<layer>/_<name>.c``; setup.py). Where no C compiler is available the
install fails. The package holds what they share: :func:`require` and the C headers
``_arrays.h`` (checked array arguments, float64 and one-byte flags), ``_kernel.h`` (a
rule's call from Python), ``_rotation.h`` (one rotation at a time), ``_homogeneous.h``
(isHomogeneousTransformation's one text), ``_envelope.h``, ``_solve6.h`` and
``_ik_core.h``. Every constant a rule needs (the cycle
``fci/tables.py`` DELTA_T among them) is passed in by its caller, never compiled in.
"""

from __future__ import annotations

import functools
import importlib
from types import ModuleType

#: The C extensions setup.py builds (one per ``<layer>/_<name>.c``), all required.
REQUIRED = (
    "fci._accounting",
    "fci._arrival",
    "fci._frames",
    "fci._measured",
    "fci._publish",
    "fci.cartesian._history",
    "fci.limits._joint",
    "fci.contact._contact",
    "sim._ik",
    "sim._dynamics",
    "sim._rows",
    "sim._truth",
    "sim._stepping",
    "sim._rotations",
    "envs._client_filters",
)


@functools.cache
def require(name: str, *functions: str) -> ModuleType:
    """The extension ``franka_sim_gym.<name>``, with each of ``functions``.

    Missing, broken, or stale (built from an older source without one of ``functions``),
    it is an ImportError at import saying so and how to build it, never an
    AttributeError inside the cycle.
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
    missing = [f for f in functions if not callable(getattr(module, f, None))]
    if missing:
        why = f"it has no {', '.join(missing)} (a stale build from an older source)"
        raise ImportError(f"{module_name}: {why}; {build}")
    return module


def describe() -> str:
    """One line for a benchmark's header: the C extensions in use (all of them, always)."""
    return f"C extensions (required): {', '.join(REQUIRED)}"


__all__ = ["REQUIRED", "describe", "require"]
