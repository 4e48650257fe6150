"""The damped differential IK's settings and result, and MuJoCo's mj_kinematics for C.

The Cartesian motion generators are judged and driven in joint space (docs/fci-behaviour.md,
The joint side of a Cartesian command): every commanded pose is solved to a joint
configuration by damped Gauss-Newton from the previous cycle's solution.
:class:`~franka_sim_gym.sim.kinematics.ArmKinematics` runs the solve; its rule (the pose
error ``[p_t - p | vee((E - E^T) / 2)]`` of ``E = R_t R^T``, the damped step
``J^T (J J^T + lambda^2 I)^-1 e`` with the elbow's column zeroed where it is held, the
step capped at :data:`MAX_STEP`, the verdicts) has one text, in C: ``sim/_ik.c`` and
``native/_ik_core.h`` (issue 38: no numpy twin), which calls MuJoCo's own
``mj_kinematics`` between its passes (:func:`mj_kinematics_addresses`).
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from .libmujoco import function_address

__all__ = [
    "ELBOW_JOINT",
    "MAX_STEP",
    "USABLE_POSITION_ERROR",
    "USABLE_ROTATION_ERROR",
    "IkResult",
    "mj_kinematics_addresses",
]

#: Joint 3 is the FR3's redundancy angle (RobotState's elbow[0] is q[2]).
ELBOW_JOINT = 2

#: The largest joint change [rad] of one Gauss-Newton update. A tracked pose moves the
#: solution by milliradians a cycle; only a jump to an unreachable pose hits this.
MAX_STEP = 0.5

#: A solution this close to its target [m, rad] still drives the servo when the solve
#: stopped short of its tolerance (near a singularity); farther, the target is
#: unreachable from here and the servo holds the last usable solution.
USABLE_POSITION_ERROR = 1e-3
USABLE_ROTATION_ERROR = 1e-2


class IkResult(NamedTuple):
    """What :meth:`ArmKinematics.solve <franka_sim_gym.sim.kinematics.ArmKinematics.solve>`
    returns."""

    #: (n, 7) joint positions.
    q: np.ndarray
    #: (n,) bool: the pose error fell below the tolerance.
    converged: np.ndarray
    #: (n,) the remaining position error [m] and rotation error [rad].
    position_error: np.ndarray
    rotation_error: np.ndarray


def mj_kinematics_addresses(model: mujoco.MjModel, data: mujoco.MjData) -> tuple | None:
    """(mj_kinematics, model, data) as addresses, for the C solve to call MuJoCo's own
    forward kinematics (sim/libmujoco.py); None where they cannot be had (ArmKinematics
    then refuses to start). The caller keeps ``model`` and ``data`` alive as long as the
    addresses are used."""
    model_address = getattr(model, "_address", None)
    data_address = getattr(data, "_address", None)
    function = function_address("mj_kinematics")
    if not model_address or not data_address or not function:
        return None
    return (function, int(model_address), int(data_address))
