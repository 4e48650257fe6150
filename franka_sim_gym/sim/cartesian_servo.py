"""The robot's internal Cartesian impedance servo (ControllerMode::kCartesianImpedance).

Under kCartesianImpedance the FR3's own controller holds the stiffness frame K on the
commanded pose like a spring (libfranka ``Robot::setCartesianImpedance``: stiffness
for x, y, z [N/m] and roll, pitch, yaw [Nm/rad], "in the direction of the stiffness
frame"). The torque, per arm:

    tau = J_K^T ( Kw e - Dw v ) + N ( Kn (q_ref - q) - Dn dq ) + C(q, dq) dq

* e = [p_d - p; e_o], the pose error of K: position, and the orientation error
  e_o = 1/2 sum_i r_i x r_d,i of the rotations' columns (Siciliano's vector error:
  sin(angle) times the axis, the rotation vector to first order; it weakens past 90
  degrees and vanishes at 180, which a commanded pose stream never comes near);
* v = J_K dq, the K frame's twist;
* Kw = R_K diag(K) R_K^T per block (the stiffness acts along K's axes), Dw the same
  with D = 2 sqrt(K Lambda): critically damped against the Cartesian inertia Lambda
  of the arm at home (its diagonal at the flange, in the base's axes, as the joint
  servo damps against the joint inertia at home, sim/arm.py; with K turned or offset
  far from the flange the damping ratio departs somewhat from 1);
* N = I - J^T (J J^T)^-1 J, the nullspace projector, with a weak joint spring toward
  q_ref that holds the elbow (``NULLSPACE_STIFFNESS``);
* gravity is compensated by the actuators as in every mode (models/fr3.xml).

Pure functions of arrays; sim/arm.py runs them inside its step.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: The nullspace's joint stiffness [Nm/rad]: weak next to the task (a 20 N/m ... 3000 N/m
#: spring at ~0.5 m from the joints is ~5 ... 750 Nm/rad), enough to keep the elbow from
#: drifting. The robot's value is not published: a choice (franka_ros's Cartesian
#: impedance example controller uses 20 as its default too).
NULLSPACE_STIFFNESS = 20.0
#: Damping of the (J J^T) solve of the nullspace projector, as in fci/contact/estimate.py's wrench.
PROJECTOR_DAMPING = 1e-8


class CartesianTarget(NamedTuple):
    """What the Cartesian servo holds, (n, ...) per arm; rows outside ``mask`` unused.

    ``position`` (n, 3) and ``rotation`` (n, 3, 3): the commanded pose of K in the base
    frame; ``flange_to_k`` (n, 4, 4): K in the flange frame (F_T_EE EE_T_K, row-major
    homogeneous); ``stiffness`` (n, 6): K_x of SetCartesianImpedance.
    """

    mask: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    flange_to_k: np.ndarray
    stiffness: np.ndarray


def orientation_error(R: np.ndarray, R_d: np.ndarray) -> np.ndarray:
    """(n, 3) 1/2 sum_i r_i x r_d,i: the rotation taking R to R_d, to first order."""
    return 0.5 * np.cross(R.transpose(0, 2, 1), R_d.transpose(0, 2, 1)).sum(axis=1)


def in_axes(R: np.ndarray, diagonal: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(n, 3) R diag(d) R^T x: a diagonal gain acting along the frame R's axes."""
    local = np.einsum("nji,nj->ni", R, x) * diagonal
    return np.einsum("nij,nj->ni", R, local)


def damping_for(stiffness: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """(n, 6) critical damping 2 sqrt(K Lambda) of a stiffness against an inertia."""
    return 2.0 * np.sqrt(stiffness * inertia)


def nullspace_projector(J: np.ndarray) -> np.ndarray:
    """(n, 7, 7) I - J^T (J J^T)^-1 J: joint torques that exert no wrench at K."""
    jjt = J @ J.transpose(0, 2, 1) + PROJECTOR_DAMPING * np.eye(6)
    pinv_t = np.linalg.solve(jjt, J)  # (J J^T)^-1 J
    return np.eye(7) - J.transpose(0, 2, 1) @ pinv_t


def impedance_torque(
    J: np.ndarray,
    position: np.ndarray,
    rotation: np.ndarray,
    target: CartesianTarget,
    damping: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    q_ref: np.ndarray,
    nullspace_damping: np.ndarray,
) -> np.ndarray:
    """(n, 7) the servo's torque without Coriolis and gravity (the caller adds them).

    ``J`` (n, 6, 7) is K's Jacobian, ``position`` / ``rotation`` K's measured pose,
    ``damping`` (n, 6) the task damping, ``nullspace_damping`` (n, 7) the nullspace's.
    """
    K = target.stiffness
    twist = np.einsum("nij,nj->ni", J, dq)
    e_p = target.position - position
    e_o = orientation_error(rotation, target.rotation)
    force = in_axes(rotation, K[:, :3], e_p) - in_axes(rotation, damping[:, :3], twist[:, :3])
    torque = in_axes(rotation, K[:, 3:], e_o) - in_axes(rotation, damping[:, 3:], twist[:, 3:])
    wrench = np.concatenate([force, torque], axis=1)
    task = np.einsum("nij,ni->nj", J, wrench)
    hold = NULLSPACE_STIFFNESS * (q_ref - q) - nullspace_damping * dq
    return task + np.einsum("nij,nj->ni", nullspace_projector(J), hold)
