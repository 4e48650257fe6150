"""The one text of the env client's per-cycle filter rules: ``envs/_client_filters.c``,
loaded and configured.

libfranka's low-pass filter, its joint, torque, twist and pose rate limiters and the
state's pose as the client reads it exist once, in C (issue 38: one text per rule; no
numpy twin, no switch). :mod:`~franka_sim_gym.envs.client_filters` and
:mod:`~franka_sim_gym.envs.cartesian_filters` put libfranka's argument checks and
broadcasting in front of them; the env's client (``commands.CommandGenerator``), which
validates its inputs once, calls :data:`RULES` every cycle. The module receives its
constants here: fci/tables.py's cycle, libfranka's ``rate_limiting.h`` values below and
the rotation library's thresholds (sim/rotations.py).

Why C: at one arm a cycle's cost is the number of its numpy calls, not their arithmetic.
The numpy texts these rules had cost 10-90 us a cycle (the pose path ~350 us), against
~1-5 us in C (benchmarks/env_rate.py ``--shares`` prints each interface's share of an env
step).
"""

from __future__ import annotations

import numpy as np

from .. import native
from ..fci.tables import DELTA_T
from ..sim import rotations

__all__ = ["NORM_EPS", "ROTATION_POSE_FACTOR", "RULES"]

#: include/franka/rate_limiting.h kNormEps: below this norm a Cartesian jerk,
#: acceleration or angular velocity counts as zero.
NORM_EPS = float(np.finfo(np.float64).eps)
#: include/franka/rate_limiting.h kFactorCartesianRotationPoseInterface: the pose
#: overload of limitRate scales the rotational limits by this factor.
ROTATION_POSE_FACTOR = 0.99

#: The rules (envs/_client_filters.c), configured. Missing or stale, importing this
#: module is an ImportError saying how to build it (native.require).
RULES = native.require(
    "envs._client_filters",
    "configure",
    "lowpass",
    "limit_velocities",
    "limit_positions",
    "JointClient",
    "limit_torques",
    "limit_twist",
    "cartesian_lowpass",
    "limit_pose",
    "reference_pose",
)
RULES.configure(
    DELTA_T,
    NORM_EPS,
    ROTATION_POSE_FACTOR,
    rotations.NEAR_PI,
    rotations.TURNING_ABOVE,
    rotations.SERIES_BELOW,
    rotations.SLERP_LINEAR,
)
