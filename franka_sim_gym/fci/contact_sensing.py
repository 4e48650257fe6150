"""The contact group of the RobotState, every cycle, and the collision reflexes (6, 7).

After physics stepped and the measured state is written: the external-torque estimate
(fci/contact.py) on the measured q, dq, tau_J and the arm's model with the configured
load; the wrench at K (O_T_EE · EE_T_K); SetCollisionBehavior's levels
(fci/collision.py). It writes ``tau_ext_hat_filtered``, ``O_F_ext_hat_K``,
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

from ..sim.arm import ArmPhysics
from ..sim.dynamics import ArmDynamics, weight_torque
from . import contact
from .collision import (
    ACCELERATION_PHASE,
    DEFAULT_FORCE_THRESHOLDS,
    DEFAULT_TORQUE_THRESHOLDS,
    THRESHOLD_NAMES,
    CollisionBehavior,
    Levels,
    accelerating,
    invalid_thresholds,
)
from .contact import (
    ALPHA,
    RESOLUTION_DECIMALS,
    WRENCH_DAMPING,
    ExternalTorqueEstimator,
    in_frame,
    wrench_from_torque,
)
from .engine import MotionLimitEngine
from .errors import Error
from .statuses import SetterStatus

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
        #: (n, 7) the measured joint torques the estimate reads (the physics', or the
        #: robot's sensors' under a reality draw: fci/reality/)
        self.tau_J = physics.tau_J
        self.dynamics = ArmDynamics(physics)
        self.estimator = ExternalTorqueEstimator(n)
        every = np.arange(n)
        self.estimator.reset(every, physics.dq, self.dynamics.mass_matrix(), self.dynamics.bias())
        #: SetCollisionBehavior's thresholds per robot
        self.behavior = CollisionBehavior(n)
        self.engine = engine
        self.enforce = enforce
        self.field = field
        self._gravity = np.asarray(physics.model.opt.gravity, dtype=float).copy()
        #: No threshold of any robot (lower or upper, either phase) ever lay below these:
        #: the defaults and every configured one. An estimate at or below both trips no
        #: comparison, whatever the thresholds are now.
        self.lowest_torque = min(DEFAULT_TORQUE_THRESHOLDS)
        self.lowest_force = min(DEFAULT_FORCE_THRESHOLDS)
        #: The frame K of every robot this cycle: origin (n, 3) and axes (n, 3, 3).
        self.k_point = np.zeros((n, 3))
        self.k_rotation = np.zeros((n, 3, 3))

    # -- configuration ----------------------------------------------------------------------

    def reset(self, robots) -> None:
        """Teleported or reconfigured ``robots``: estimate from zero, flags clear,
        thresholds back to the defaults."""
        robots = np.atleast_1d(np.asarray(robots, dtype=np.intp))
        dynamics = self.dynamics
        mass, bias = dynamics.mass_matrix()[robots], dynamics.bias()[robots]
        self.estimator.reset(robots, self.physics.dq[robots], mass, bias)
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
        torque = [values[name].min() for name in THRESHOLD_NAMES if "torque" in name]
        force = [values[name].min() for name in THRESHOLD_NAMES if "force" in name]
        self.lowest_torque = min(self.lowest_torque, *torque)
        self.lowest_force = min(self.lowest_force, *force)
        log.info(
            "robot %d: SetCollisionBehavior: upper thresholds %s Nm, %s N/Nm (nominal phase)",
            i,
            values["upper_torque_thresholds_nominal"].tolist(),
            values["upper_force_thresholds_nominal"].tolist(),
        )
        return SetterStatus.kSuccess

    def sense(self, in_motion: np.ndarray, load_weight: np.ndarray | None) -> None:
        """Estimate, write the contact group, judge the thresholds (after the state's
        measured fields are written)."""
        physics, f = self.physics, self.field
        # The model at the state the step started from, paired with the torque of that
        # step (contact.py, ExternalTorqueEstimator); the load's weight is of that state
        # too (the controller computes it before the step).
        dynamics = self.dynamics
        m_ddq, bias = self.estimator.model_terms(
            physics.dq, dynamics.mass_matrix(), dynamics.bias()
        )
        if load_weight is not None:
            bias = bias + load_weight
        point, rotation = self.k_point, self.k_rotation
        rules = contact.RULES  # the backend switch (contact.py)
        rules.k_frame(f["O_T_EE"], f["EE_T_K"], point, rotation)
        jacobian = self.dynamics.jacobian(point)
        tau, wrench = f["tau_ext_hat_filtered"], f["O_F_ext_hat_K"]
        if rules is not contact.NUMPY_RULES:
            # The numpy steps below in one C call (fci/_contact.c sense, held to them by
            # tests/fci/test_contact_parity.py): the flags written, the robots over an
            # upper threshold counted.
            over = rules.sense(
                self.estimator.tau_ext, self.tau_J, m_ddq, bias, jacobian, rotation,
                f["ddq_d"], in_motion, self.behavior.thresholds,
                ALPHA, WRENCH_DAMPING, RESOLUTION_DECIMALS, ACCELERATION_PHASE,
                tau, wrench, f["K_F_ext_hat_K"], f["joint_contact"], f["cartesian_contact"],
            )  # fmt: skip
            if not over:
                return
        else:
            self.estimator.filter(self.tau_J, m_ddq, bias, tau)
            wrench_from_torque(jacobian, tau, wrench)
            in_frame(wrench, rotation, f["K_F_ext_hat_K"])
            quiet = np.abs(tau).max() <= self.lowest_torque
            if quiet and np.abs(wrench).max() <= self.lowest_force:
                # At or below every threshold: no comparison (a strict ">") can trip, so
                # the levels are all clear without comparing (a NaN fails this test and
                # takes the comparisons).
                f["joint_contact"][...] = 0.0
                f["cartesian_contact"][...] = 0.0
                return
        phase = accelerating(f["ddq_d"], in_motion)
        levels = self.behavior.levels(tau, wrench, phase)
        f["joint_contact"][...] = levels.joint_contact
        f["cartesian_contact"][...] = levels.cartesian_contact
        if np.count_nonzero(levels.joint_over) or np.count_nonzero(levels.cartesian_over):
            self._collide(levels, in_motion & self.engine.live(in_motion), phase, tau, wrench)

    def _collide(self, levels: Levels, rows: np.ndarray, phase, tau, wrench) -> None:
        """Latch the collision flags of the robots in motion (``rows``) that crossed an
        upper threshold, and report 6 / 7 (one abort latching both when both)."""
        b = self.behavior
        over = rows & (levels.joint_over.any(axis=1) | levels.cartesian_over.any(axis=1))
        for i in np.flatnonzero(over).tolist():
            p = 0 if phase[i] else 1
            checks = (
                (Error.joint_reflex, "joint_collision", levels.joint_over[i], tau[i],
                 b.upper_torque[i, p], [f"joint {j + 1}" for j in range(7)], "external torque"),
                (Error.cartesian_reflex, "cartesian_collision", levels.cartesian_over[i],
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
