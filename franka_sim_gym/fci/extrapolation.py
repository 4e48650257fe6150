"""The lost-cycle laws, one per commanded signal (docs/fci-behaviour.md "What the sim does with a
lost cycle").

The robot continues a motion signal it did not hear from the client at the
highest derivative the last two real commands implied, frozen, integrating
below it ("keep acceleration constant and integrate", libfranka
docs/system_requirements.rst):

| signal | law for one missed cycle |
|---|---|
| q_c | semi-implicit Euler: v += a dt, then q += v dt; a frozen |
| dq_c | dq += a dt; a frozen, no jerk term |
| O_T_EE_c | translation per axis by the q_c law; rotation composed on the |
|          | right by the axis-angle increment (omega + alpha dt) dt       |
| O_dP_EE_c | twist extended at the frozen twist acceleration |
| elbow_c | elbow[0] by the q_c law; elbow[1] (a branch flag) held |
| tau_J_d | held |

All functions are pure and batch-first (leading robot axis). The q_c and dq_c laws'
only text is C (fci/limits/_joint.c ``position_law`` / ``velocity_law``): the joint
generators' cycle applies them itself (``JointCycle``), the Cartesian generators
through these functions (``cartesian.step``).
"""

from __future__ import annotations

import numpy as np

from .. import native
from ..sim.rotations import rotation_exp
from .tables import DELTA_T

#: the q_c and dq_c laws' C text (a required extension: there is no other)
_LAWS = native.require("fci.limits._joint", "position_step", "velocity_step")


def position_step(
    x: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float = DELTA_T
) -> tuple[np.ndarray, np.ndarray]:
    """q_c (and translation, elbow[0]): semi-implicit Euler at frozen ``a``; (x', v').

    ``x``, ``v``, ``a``: (m,) or (m, k) arrays of one shape."""
    return _LAWS.position_step(*_float64(x, v, a), dt)


def velocity_step(v: np.ndarray, a: np.ndarray, dt: float = DELTA_T) -> np.ndarray:
    """dq_c and O_dP_EE_c: the velocity (twist) continued at the frozen acceleration."""
    return _LAWS.velocity_step(*_float64(v, a), dt)


def _float64(*arrays) -> tuple[np.ndarray, ...]:
    return tuple(np.asarray(x, dtype=np.float64) for x in arrays)


def pose_step(
    T: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    omega: np.ndarray,
    alpha: np.ndarray,
    dt: float = DELTA_T,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """O_T_EE_c: translation by the semi-implicit law, rotation composed on the right by
    the axis-angle increment (omega + alpha dt) dt.

    Args:
        T: (n, 4, 4) row-major poses; v, a: (n, 3) translational velocity and
            (frozen) acceleration; omega, alpha: (n, 3) angular velocity and
            (frozen) angular acceleration.

    Returns:
        (T', v', omega') the extrapolated pose and velocities.
    """
    T_next = np.array(T, dtype=np.float64, copy=True)
    p_next, v_next = position_step(T[..., :3, 3], v, a, dt)
    omega_next = omega + alpha * dt
    T_next[..., :3, 3] = p_next
    T_next[..., :3, :3] = T[..., :3, :3] @ rotation_exp(omega_next * dt)
    return T_next, v_next, omega_next


def elbow_step(
    elbow: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float = DELTA_T
) -> tuple[np.ndarray, np.ndarray]:
    """elbow_c: elbow[0] by the position law; the branch flag elbow[1] is held."""
    e = np.array(elbow, dtype=np.float64, copy=True)
    e[..., 0], v_next = position_step(e[..., 0], v, a, dt)
    return e, v_next
