"""Validation of the setter commands (ids 3-9): which arguments the robot refuses.

What the real robot rejects with kInvalidArgumentRejected is not published
(docs/wire-protocol.md §3.2); we refuse what cannot be meant: non-finite
values, a frame that is not a homogeneous transformation (libfranka's own
client-side test), a negative mass, a stiffness outside the documented range.
"""

from __future__ import annotations

import logging

import numpy as np

from . import frames
from .wire.statuses import SetterStatus

log = logging.getLogger("franka_sim_gym.fci")

#: docs/wire-protocol.md §3.2: SetJointImpedance documents 0 ... 14250 Nm/rad per joint.
MAX_JOINT_STIFFNESS = 14250.0


def _reject(name: str, robot: int, why: str) -> SetterStatus:
    log.warning("robot %d: %s rejected: %s", robot, name, why)
    return SetterStatus.kInvalidArgumentRejected


def check_finite(name: str, robot: int, values) -> SetterStatus:
    """Accepted-but-not-simulated setters: any finite values are acknowledged."""
    if not np.all(np.isfinite(np.asarray(values, dtype=float))):
        return _reject(name, robot, "non-finite argument")
    log.info("robot %d: %s acknowledged (accepted, not simulated)", robot, name)
    return SetterStatus.kSuccess


def check_transform(name: str, robot: int, T) -> SetterStatus:
    """A 16-value column-major frame must pass libfranka's isHomogeneousTransformation."""
    values = np.asarray(T, dtype=float).reshape(-1)
    if values.shape != (16,) or not frames.is_homogeneous_transformation(values):
        return _reject(name, robot, "not a homogeneous transformation")
    return SetterStatus.kSuccess


def check_load(robot: int, m_load: float, F_x_Cload, I_load) -> SetterStatus:
    values = np.concatenate([[m_load], np.ravel(F_x_Cload), np.ravel(I_load)]).astype(float)
    if values.shape != (13,) or not np.all(np.isfinite(values)) or m_load < 0:
        return _reject("SetLoad", robot, f"invalid load {values.tolist()}")
    return SetterStatus.kSuccess


def invalid_joint_stiffness(K_theta) -> str | None:
    """Why a SetJointImpedance payload is refused (7 finite values in 0 ... 14250 Nm/rad),
    or None."""
    K = np.asarray(K_theta, dtype=float).reshape(-1)
    if K.shape != (7,) or not np.all(np.isfinite(K)) or np.any((K < 0) | (K > MAX_JOINT_STIFFNESS)):
        return f"K_theta {K.tolist()} outside 0..14250"
    return None


def check_joint_stiffness(robot: int, K_theta) -> SetterStatus:
    why = invalid_joint_stiffness(K_theta)
    if why is not None:
        return _reject("SetJointImpedance", robot, why)
    return SetterStatus.kSuccess
