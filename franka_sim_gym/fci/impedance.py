"""The internal servo under ControllerMode::kCartesianImpedance: what it holds, how stiff.

A Move with controller mode kCartesianImpedance makes the robot's own controller a
Cartesian spring on the stiffness frame K (sim/cartesian_servo.py simulates it). It
holds K where the motion generator's reference puts it: the forward kinematics of the
joint reference the controller hands the servo (q_d under the joint generators, the
IK's solution of the commanded pose under the Cartesian ones), with K = F_T_EE · EE_T_K
on the flange; the same joint reference is the nullspace's target, holding the elbow.

SetCartesianImpedance sets the stiffness (x, y, z in N/m, documented 10 ... 3000; roll,
pitch, yaw in Nm/rad, 1 ... 300; libfranka ``Robot::setCartesianImpedance``) from the
next cycle; values outside those ranges or non-finite are refused. Before any call, the
values Franka's examples set (libfranka ``examples/examples_common.cpp``,
``setDefaultBehavior``): the robot's factory value is not published, so a choice.
"""

from __future__ import annotations

import logging

import numpy as np

from ..sim.cartesian_servo import CartesianTarget
from ..sim.kinematics import ArmKinematics
from .wire.statuses import SetterStatus

log = logging.getLogger("franka_sim_gym.fci")

#: K_x before any SetCartesianImpedance [N/m, N/m, N/m, Nm/rad, Nm/rad, Nm/rad].
DEFAULT_CARTESIAN_STIFFNESS = (3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0)
#: libfranka robot.h, setCartesianImpedance: the documented ranges per axis.
CARTESIAN_STIFFNESS_MIN = np.array([10.0, 10.0, 10.0, 1.0, 1.0, 1.0])
CARTESIAN_STIFFNESS_MAX = np.array([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])


def invalid_stiffness(K_x) -> str | None:
    """Why a SetCartesianImpedance payload is refused, or None."""
    K = np.asarray(K_x, dtype=float).reshape(-1)
    if K.shape != (6,) or not np.all(np.isfinite(K)):
        return f"K_x {K.tolist()}: six finite values expected"
    if np.any((K < CARTESIAN_STIFFNESS_MIN) | (K > CARTESIAN_STIFFNESS_MAX)):
        return f"K_x {K.tolist()} outside 10 ... 3000 N/m, 1 ... 300 Nm/rad"
    return None


class CartesianImpedance:
    """The Cartesian servo's stiffness per robot, and its target each cycle."""

    def __init__(self, kinematics: ArmKinematics, n: int) -> None:
        self.kinematics = kinematics
        #: (n, 6) SetCartesianImpedance's K_x
        self.stiffness = np.tile(DEFAULT_CARTESIAN_STIFFNESS, (n, 1))

    def reset(self, i: int) -> None:
        self.stiffness[i] = DEFAULT_CARTESIAN_STIFFNESS

    def configure(self, i: int, K_x) -> SetterStatus:
        """SetCartesianImpedance for robot i: applied from the next cycle, or refused
        (nothing changes), logged either way."""
        why = invalid_stiffness(K_x)
        if why is not None:
            log.warning("robot %d: SetCartesianImpedance rejected: %s", i, why)
            return SetterStatus.kInvalidArgumentRejected
        self.stiffness[i] = np.ravel(np.asarray(K_x, dtype=float))
        log.info("robot %d: SetCartesianImpedance: K_x %s", i, self.stiffness[i])
        return SetterStatus.kSuccess

    def target(
        self,
        mask: np.ndarray,
        q_ref: np.ndarray,
        F_T_EE: np.ndarray,
        EE_T_K: np.ndarray,
        stiffness: np.ndarray | None = None,
    ) -> CartesianTarget:
        """What the servo of the ``mask`` robots holds this cycle: K at FK(q_ref), with
        ``stiffness`` (n, 6) (default: SetCartesianImpedance's, :attr:`stiffness`)."""
        flange_to_k = F_T_EE @ EE_T_K
        T = self.kinematics.forward(q_ref, flange_to_k)
        K = self.stiffness if stiffness is None else stiffness
        return CartesianTarget(mask, T[:, :3, 3], T[:, :3, :3], flange_to_k, K)
