"""The contact group of the RobotState, every cycle, and the collision reflexes (6, 7).

After physics stepped and the measured state is written: the external-torque estimate
(fci/contact/estimate.py) on the measured q, dq, tau_J and the arm's model with the configured
load; the wrench at K (O_T_EE · EE_T_K); SetCollisionBehavior's levels
(fci/contact/collision.py). It writes ``tau_ext_hat_filtered``, ``O_F_ext_hat_K``,
``K_F_ext_hat_K``, ``joint_contact`` and ``cartesian_contact`` every cycle, latches
``joint_collision`` / ``cartesian_collision`` during a motion, and reports
``joint_reflex`` (6) / ``cartesian_reflex`` (7) to the engine like the safety
controller's checks: logged always, the motion aborted when motion limits are enforced.

Where it sits: on the measured state, beside the safety controller (errors 2, 3, 4)
and outside every generator's precedence chain; when one cycle trips both, the robot
latches both (docs/motion-limits.md).
"""

from __future__ import annotations

import logging

import numpy as np

from ...sim.arm import ArmPhysics
from ...sim.dynamics import ArmDynamics, weight_torque
from ..engine import MotionLimitEngine
from ..errors import Error
from ..tables import DELTA_T
from ..wire.statuses import SetterStatus
from . import estimate as contact
from .collision import (
    ACCELERATION_PHASE,
    THRESHOLD_NAMES,
    CollisionBehavior,
    invalid_thresholds,
)
from .estimate import ALPHA, RESOLUTION_DECIMALS, WRENCH_DAMPING, ExternalTorqueEstimator

_AXES = ("x", "y", "z", "R", "P", "Y")
log = logging.getLogger("franka_sim_gym.fci")


class ContactSensing:
    """What n robots sense of contact, and their collision thresholds.

    Args:
        physics: the simulated arms (measured state and model terms).
        field: the state writer's float64 views of the wire fields, by name.
        engine: reports violations and turns enforced ones into verdicts.
        enforce: abort a motion on a collision (``--enforce-motion-limits``).
    """

    def __init__(
        self,
        physics: ArmPhysics,
        field: dict[str, np.ndarray],
        engine: MotionLimitEngine,
        enforce: bool,
    ) -> None:
        n = physics.n
        self.physics = physics
        self._plan = None  # the C plan of a cycle (fci/contact/_contact.c Sensing)
        self.tau_J = physics.tau_J
        self.dynamics = ArmDynamics(physics)
        self.estimator = ExternalTorqueEstimator(n)
        #: SetCollisionBehavior's thresholds per robot
        self.behavior = CollisionBehavior(n)
        self.engine = engine
        self.enforce = enforce
        self.field = field
        self._gravity = np.asarray(physics.model.opt.gravity, dtype=float).copy()
        #: The frame K of every robot this cycle: origin (n, 3) and axes (n, 3, 3).
        self.k_point = np.zeros((n, 3))
        self.k_rotation = np.zeros((n, 3, 3))
        #: This cycle's components over an upper threshold, (n, 7) joints and (n, 6)
        #: Cartesian axes (1.0 / 0.0), and the robots in their acceleration phase (n,).
        self.joint_over = np.zeros((n, 7))
        self.cartesian_over = np.zeros((n, 6))
        self.accelerating = np.zeros(n, dtype=np.uint8)
        #: this cycle's model terms of the step that ended: M ddq and the bias (plus a
        #: configured load's weight), and the Jacobian at K
        self.m_ddq = np.zeros((n, 7))
        self.loaded_bias = np.zeros((n, 7))
        self.jacobian = np.zeros((n, 6, 7))
        self._planned().reset(np.arange(n, dtype=np.int64))  # the estimate starts at rest

    @property
    def tau_J(self) -> np.ndarray:
        """(n, 7) the measured joint torques the estimate reads (the physics', or the
        robot's sensors' under a reality draw: fci/reality/)."""
        return self._tau_J

    @tau_J.setter
    def tau_J(self, tau_J: np.ndarray) -> None:
        self._tau_J = tau_J
        self._plan = None

    # -- configuration ----------------------------------------------------------------------

    def reset(self, robots) -> None:
        """Teleported or reconfigured ``robots``: estimate from zero, flags clear,
        thresholds back to the defaults."""
        robots = np.atleast_1d(np.asarray(robots, dtype=np.int64))
        self._planned().reset(robots)
        for name in ("tau_ext_hat_filtered", "O_F_ext_hat_K", "K_F_ext_hat_K"):
            self.field[name][robots] = 0.0
        for name in ("joint_contact", "cartesian_contact"):
            self.field[name][robots] = 0.0
        for i in robots.tolist():
            self.behavior.reset(i)
            self.clear(i)

    def clear(self, i: int) -> None:
        """AutomaticErrorRecovery: the latched collision flags of robot i clear."""
        self.field["joint_collision"][i] = 0.0
        self.field["cartesian_collision"][i] = 0.0

    # -- the model with the configured load -------------------------------------------------

    def load_weight(self) -> np.ndarray | None:
        """(n, 7) the torque that holds each robot's configured load (SetLoad: m_load at
        F_x_Cload in the flange frame) against gravity; None when no load is configured.
        The drives apply it in every mode, and the model the estimate runs on includes it."""
        mass = self.field["m_load"]
        if not np.count_nonzero(mass):
            return None
        p, R = self.physics.flange_pose()
        com = p + np.einsum("nij,nj->ni", R, self.field["F_x_Cload"])
        return weight_torque(self.dynamics.jacobian(com), mass, self._gravity)

    # -- the cycle --------------------------------------------------------------------------

    def configure(self, i: int, thresholds) -> SetterStatus:
        """SetCollisionBehavior for robot i (the eight arrays by name): stored from the
        next cycle on, or refused (nothing stored), logged either way."""
        values = {name: np.asarray(thresholds[name], dtype=float) for name in THRESHOLD_NAMES}
        why = invalid_thresholds(values)
        if why is not None:
            log.warning("robot %d: SetCollisionBehavior rejected: %s", i, why)
            return SetterStatus.kInvalidArgumentRejected
        self.behavior.configure(i, values)
        log.info(
            "robot %d: SetCollisionBehavior: upper thresholds %s Nm, %s N/Nm (nominal phase)",
            i,
            values["upper_torque_thresholds_nominal"].tolist(),
            values["upper_force_thresholds_nominal"].tolist(),
        )
        return SetterStatus.kSuccess

    def sense(self, in_motion: np.ndarray, load_weight: np.ndarray | None) -> None:
        """Estimate, write the contact group, judge the thresholds (after the state's
        measured fields are written).

        The model at the state the step started from, paired with the torque of that step
        (estimate.py, ExternalTorqueEstimator); the load's weight is of that state too (the
        controller computes it before the step). One C call: the model terms, the
        estimate, the wrench at K and in K's axes, the collision levels."""
        if self._planned().run(in_motion, load_weight):
            f = self.field
            self._collide(
                in_motion & self.engine.live(in_motion),
                f["tau_ext_hat_filtered"],
                f["O_F_ext_hat_K"],
            )

    def _planned(self):
        """The C plan of a cycle's sensing (fci/contact/_contact.c Sensing), made where
        the arrays it holds changed."""
        if self._plan is None:
            self._plan = contact.RULES.Sensing(*self.plan_arrays())
        return self._plan

    def plan_arrays(self) -> tuple:
        """What the C plan of a cycle's sensing holds, in its order: the arrays it reads
        and writes (MuJoCo's rows of the model terms, the estimator's state, the state
        writer's fields, this object's scratch and levels) and the constants."""
        physics, f, est = self.physics, self.field, self.estimator
        qM, block, qfrc_bias, passive, payload = self.dynamics.model_rows()
        return (
            qM, block, qfrc_bias, passive, payload, physics.dq, est.dq_prev, est.mass,
            est.bias, f["O_T_EE"], f["EE_T_K"], physics.joint_axes, physics.joint_anchors,
            self.k_point, self.k_rotation, self.jacobian, self.tau_J, f["ddq_d"],
            self.behavior.thresholds, est.tau_ext, self.m_ddq, self.loaded_bias,
            f["tau_ext_hat_filtered"], f["O_F_ext_hat_K"], f["K_F_ext_hat_K"],
            f["joint_contact"], f["cartesian_contact"], self.joint_over, self.cartesian_over,
            self.accelerating,
            (ALPHA, WRENCH_DAMPING, RESOLUTION_DECIMALS, ACCELERATION_PHASE, DELTA_T),
        )  # fmt: skip

    def _collide(self, rows: np.ndarray, tau: np.ndarray, wrench: np.ndarray) -> None:
        """Latch the collision flags of the robots in motion (``rows``) that crossed an
        upper threshold this cycle, and report 6 / 7 (one abort latching both when both)."""
        b = self.behavior
        joint_over, cartesian_over = self.joint_over > 0, self.cartesian_over > 0
        over = rows & (joint_over.any(axis=1) | cartesian_over.any(axis=1))
        for i in np.flatnonzero(over).tolist():
            p = 0 if self.accelerating[i] else 1
            checks = (
                (Error.joint_reflex, "joint_collision", joint_over[i], tau[i],
                 b.upper_torque[i, p], [f"joint {j + 1}" for j in range(7)], "external torque"),
                (Error.cartesian_reflex, "cartesian_collision", cartesian_over[i],
                 wrench[i], b.upper_force[i, p], _AXES, "external wrench at K"),
            )  # fmt: skip
            bits = []
            for error, flags, over_i, value, upper, names, what in checks:
                crossed = np.flatnonzero(over_i)
                if not len(crossed):
                    continue
                self.field[flags][i, crossed] = 1.0
                detail = ", ".join(
                    f"{names[k]} {value[k]:+.1f} (upper {upper[k]:g})" for k in crossed
                )
                self.engine.report(i, int(error), f"{what} {detail}", self.enforce)
                bits.append(int(error))
            if self.enforce:
                self.engine.abort(i, bits)
