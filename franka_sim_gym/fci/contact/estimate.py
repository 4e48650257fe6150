"""What the robot senses of contact: its external-torque estimate and the wrench at K.

The FR3 has no force sensor at the flange. It estimates the external torque from its
dynamic model and its link-side joint torque sensors, and the external wrench from
that torque through the Jacobian of the stiffness frame K (libfranka
``include/franka/robot_state.h``: ``tau_ext_hat_filtered``, ``O_F_ext_hat_K``,
``K_F_ext_hat_K``). This module is that estimator, run on what the simulation
measures (q, dq, tau_J) and on the arm's model terms (sim/dynamics.py); MuJoCo's
contact forces are never read, they are the ground truth the tests hold it to.

The estimate is the model's residual, low-pass filtered:

    tau_ext_hat = LPF( tau_J - (M(q) ddq + C(q, dq) dq + g(q)) ),

with ddq the measured velocity's backward difference over the 1 ms cycle. It is what
the motor torques did not account for: at rest in free space zero; pressing on a
table, tau_J = g - J^T F_c (F_c: the table's force on the arm), so
tau_ext_hat = -J^T F_c = J^T F, F the force the robot exerts. O_F_ext_hat_K is that F
at K: pressing down on a table reads a negative z force, as franky's own reaction
example relies on (``Reaction(Measure.FORCE_Z < -5.0, ...)`` stops a motion down
that is blocked).

A generalized-momentum observer (De Luca et al. 2006) avoids the differentiated
velocity a real robot's noisy encoders make unusable; the simulation's velocities
carry no sensor noise, so the residual with a first-order filter gives the same
estimate at a fraction of the cost (docs/robot-state.md, the contact group).

The rules (the model terms' M ddq, the filter step, the frame K, the wrench at K, its
copy in K's axes, and the whole cycle's step with the collision levels,
fci/contact/sensing.py) have one text, C: ``fci/contact/_contact.c`` (issue 38: one
text per rule, compiled), :data:`RULES`.
"""

from __future__ import annotations

import numpy as np

from ... import native
from ..tables import DELTA_T

__all__ = [
    "RULES",
    "ExternalTorqueEstimator",
    "in_frame",
    "wrench_from_torque",
]

#: Time constant of the estimate's low-pass filter [s]. Not published for the FR3: a
#: choice. 10 ms (16 Hz) passes a press on a table within a few cycles and smooths
#: the single-cycle spikes of an impact, which a 1 ms residual would report at
#: hundreds of N.
ESTIMATE_TIME_CONSTANT = 0.01
#: The filter's per-cycle gain: y += ALPHA (x - y), the discrete first-order low-pass.
ALPHA = DELTA_T / (ESTIMATE_TIME_CONSTANT + DELTA_T)
#: Decimals the estimate is published with: 0.1 mNm and 0.1 mN (a choice, far below
#: any threshold). The published value carries no last-bit noise of the differentiated
#: velocity (~1e-14 Nm), so a client comparing two runs' wrenches sees what physics
#: changed, not how the arithmetic rounded.
RESOLUTION_DECIMALS = 4
#: Damping of the wrench's least-squares solve [m^2 units of J J^T]: keeps the 6 x 6
#: system solvable at a singularity; 1e-8 moves a regular pose's wrench by < 1e-6.
WRENCH_DAMPING = 1e-8


#: The rules' only text (fci/contact/_contact.c; a required extension: there is no other).
RULES = native.require(
    "fci.contact._contact",
    "filter_residual",
    "wrench_from_torque",
    "in_frame",
    "k_frame",
    "sense",
    "Sensing",
)


def wrench_from_torque(
    jacobian: np.ndarray, tau: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """(n, 6) the wrench F at the Jacobian's point with J^T F = tau, least squares.

    A 7-joint arm maps a 6-dof wrench one to one (away from singularities); a torque
    no wrench there can cause (a contact on an inner link) gets its least-squares
    wrench, as a robot estimating at K reports it. Damped by :data:`WRENCH_DAMPING`,
    published at :data:`RESOLUTION_DECIMALS` (into ``out`` where given).
    """
    if out is None:
        out = np.empty((len(jacobian), 6))
    return RULES.wrench_from_torque(jacobian, tau, WRENCH_DAMPING, RESOLUTION_DECIMALS, out)


def in_frame(wrench: np.ndarray, rotation: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(n, 6) a base-frame wrench expressed in a frame whose axes are ``rotation``'s
    columns (n, 3, 3): K_F_ext_hat_K from O_F_ext_hat_K (R^T f and R^T m, as rows
    f R and m R), into ``out`` where given."""
    if out is None:
        out = np.empty((len(wrench), 6))
    return RULES.in_frame(wrench, rotation, RESOLUTION_DECIMALS, out)


class ExternalTorqueEstimator:
    """The filtered model residual of n robots: the estimate's state.

    The residual of a cycle pairs the torque the drives applied during its step with the
    model at the state that step started from: MuJoCo's step integrates
    M(q_k) ddq = tau_k - bias(q_k, dq_k) + (contact) from state k to k + 1, and the torque
    it measures (``qfrc_actuator``, gravity compensation included) is the one of state k.
    So the estimator keeps the model terms of the last state it saw for the next cycle.

    The cycle's arithmetic (the model terms, ddq, M ddq, the filter step) is
    fci/contact/_contact.c's ``Sensing``, which fci/contact/sensing.py runs once per cycle
    after physics stepped on these arrays; its ``reset`` restarts a teleported robot's
    estimate (a velocity jump is no acceleration).
    """

    def __init__(self, n: int) -> None:
        #: the velocity of the state the next step starts from
        self.dq_prev = np.zeros((n, 7))
        #: the filtered estimate, tau_ext_hat_filtered (robot convention: J^T F)
        self.tau_ext = np.zeros((n, 7))
        #: M (n, 7, 7) and the bias C dq + g + friction (n, 7) of the state the next step
        #: starts from
        self.mass = np.zeros((n, 7, 7))
        self.bias = np.zeros((n, 7))
