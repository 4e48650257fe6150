"""The backend of the env client's per-cycle filter rules: numpy, or their C replacements.

Every rule the client runs each cycle is a ``*_core`` function of
:mod:`~franka_sim_gym.envs.client_filters` or :mod:`~franka_sim_gym.envs.cartesian_filters`
(the reference, written once, batch-first). ``envs/_client_filters.c`` holds a C
replacement of each, with its signature (``out`` given): the low-pass filter and the
joint, torque and twist limiters bit for bit, the pose rules to rounding
(tests/envs/test_native_client.py). The one backend switch (``native.load``,
``FRANKA_SIM_GYM_NATIVE=0`` for numpy) picks them; the C module receives its constants
here: fci/tables.py's cycle, libfranka's rate_limiting.h values in cartesian_filters.py
and the rotation library's thresholds (sim/rotations.py).

Why C at all: at one arm a cycle's cost is the number of numpy calls, not their
arithmetic. The numpy rules cost 10-90 us a cycle (the pose path ~350 us), against
~25 us for the rest of a cycle; their C replacements ~1-5 us (benchmarks/env_rate.py
``--shares`` prints each interface's share of an env step).
"""

from __future__ import annotations

from types import ModuleType, SimpleNamespace

from .. import native
from ..fci.tables import DELTA_T
from ..sim import rotations
from . import cartesian_filters as cartesian
from . import client_filters as joint

__all__ = ["NUMPY_RULES", "load", "rules"]

#: The numpy rules, by the names the C module gives its replacements.
NUMPY_RULES = SimpleNamespace(
    lowpass_core=joint.lowpass_core,
    limit_velocities_core=joint.limit_velocities_core,
    limit_positions_core=joint.limit_positions_core,
    limit_torques_core=joint.limit_torques_core,
    limit_twist_core=cartesian.limit_twist_core,
    cartesian_lowpass_core=cartesian.cartesian_lowpass_core,
    limit_pose_core=cartesian.limit_pose_core,
    reference_pose=cartesian.reference_pose,
)


def load() -> ModuleType | None:
    """The C replacements (configured), or None where not built or switched off."""
    kernel = native.load("envs._client_filters")
    if kernel is not None:
        kernel.configure(
            DELTA_T,
            cartesian.NORM_EPS,
            cartesian.ROTATION_POSE_FACTOR,
            rotations.NEAR_PI,
            rotations.TURNING_ABOVE,
            rotations.SERIES_BELOW,
        )
    return kernel


def rules(kernel: ModuleType | None) -> ModuleType | SimpleNamespace:
    """The rules a client runs: ``kernel``'s where given, else :data:`NUMPY_RULES`."""
    return NUMPY_RULES if kernel is None else kernel
