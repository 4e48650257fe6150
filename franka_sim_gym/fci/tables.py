"""Robot tables: every limit the simulated controller enforces, one table per robot.

Two robots are selectable: the FR3 behind FCI v10 (libfranka >= 0.18) and the
FER ("Panda") behind FCI v5 (libfranka 0.9.x). Every number cites where it
comes from; `docs/limits.md` collects the sources. Server-side checks
use the *robot's* limits; libfranka's `rate_limiting.h` constants are those
minus kLimitEps = 1e-3 (the limiter's target, so that a rate-limited command
never touches the robot's threshold). The robot's threshold is taken as
"limit - 1e-3" (docs/fci-behaviour.md "What is checked, and what it latches").
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .. import native

#: libfranka include/franka/rate_limiting.h: kDeltaT, the 1 kHz cycle.
DELTA_T = 1e-3
#: libfranka rate_limiting.h: kLimitEps.
LIMIT_EPS = 1e-3
#: libfranka joint_velocity_limits.cpp: tolerance subtracted from the envelope.
JOINT_VELOCITY_LIMIT_TOLERANCE = 1e-3
#: Franka docs "Control Interface Specification": >= 20 consecutive lost
#: packets abort the motion with communication_constraints_violation.
MAX_LOST_CYCLES = 20
#: libfranka docs: control_command_success_rate covers the last 100 commands.
SUCCESS_RATE_WINDOW = 100
#: Gravity published in O_ddP_O; libfranka docs: "fixed to (0, 0, -9.81)".
#: libfranka's Model::gravity(state) uses this field as the gravity vector.
GRAVITY = (0.0, 0.0, -9.81)
#: docs/limits.md §2.2: joint-4 angle of maximum extension (FER and FR3 alike).
ELBOW_FLIP_Q4 = -0.467002423653011


def _ro(values) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class RobotTable:
    """The limits of one robot model, as the controller behind one FCI version enforces them."""

    name: str
    fci_version: int
    #: joint range [rad] (FR3: the served URDF <limit lower/upper>, docs/limits.md §2.1 (a)).
    q_lower: np.ndarray
    q_upper: np.ndarray
    #: nameplate joint velocity [rad/s] (URDF <limit velocity>).
    dq_max: np.ndarray
    #: position-based envelope parameters (URDF <position_based_velocity_limits>);
    #: None for a robot with constant velocity limits (the FER).
    dq_offset: np.ndarray | None
    ddq_decel: np.ndarray | None
    #: kMaxJointAcceleration / kMaxJointJerk: robot limit minus 1e-3 (docs/limits.md §1).
    ddq_max: np.ndarray
    dddq_max: np.ndarray
    #: URDF <limit effort> [Nm].
    tau_max: np.ndarray
    #: kMaxTorqueRate = 1000 - 1e-3 Nm/s (rate_limiting.h, docs/limits.md §1).
    dtau_max: float
    #: Cartesian translational / rotational velocity, acceleration, jerk (docs/limits.md §1).
    v_trans_max: float
    a_trans_max: float
    j_trans_max: float
    v_rot_max: float
    a_rot_max: float
    j_rot_max: float
    #: elbow velocity / acceleration / jerk (docs/limits.md §1: kMaxElbow*).
    v_elbow_max: float
    a_elbow_max: float
    j_elbow_max: float
    #: joint side of a Cartesian command (errors 29/30): per-joint tables.
    ik_ddq_max: np.ndarray = field(default_factory=lambda: _ro(np.zeros(7)))
    ik_dddq_max: np.ndarray = field(default_factory=lambda: _ro(np.zeros(7)))

    @cached_property
    def joint_constants(self) -> tuple[np.ndarray, float]:
        """The joint limits as the C texts of the rules take them (fci/limits/_joint.c):
        (7, 7) rows q_lower, q_upper, ddq_max, dddq_max, 2 ddq_decel, dq_offset, dq_max,
        read-only, and 1.0 where the envelope depends on the position (0.0: the constant
        dq_max of a robot without offsets)."""
        positional = self.dq_offset is not None
        zero = np.zeros(7)
        rows = (
            self.q_lower,
            self.q_upper,
            self.ddq_max,
            self.dddq_max,
            2.0 * self.ddq_decel if positional else zero,
            self.dq_offset if positional else zero,
            self.dq_max,
        )
        return _ro(np.stack(rows)), float(positional)

    def velocity_envelope(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The admissible joint velocity band at q, shape (..., 7) each.

        libfranka >= 0.18 src/joint_velocity_limits.cpp (docs/limits.md §4):
        upper = min(v_max, max(0, -v_off + sqrt(max(0, 2 a_dec (q_max - q))))) - tol,
        lower = max(-v_max, min(0, v_off - sqrt(max(0, 2 a_dec (q - q_min))))) + tol.
        """
        r = self.velocity_envelope_halves(q)
        return r[..., :7], -r[..., 7:]

    def velocity_envelope_halves(
        self, q: np.ndarray, shift: float | np.ndarray = JOINT_VELOCITY_LIMIT_TOLERANCE
    ) -> np.ndarray:
        """(..., 14): [upper | -lower] of :meth:`velocity_envelope` at ``q`` (..., 7) (lower
        is the same law on the mirrored range), with ``shift`` in place of the tolerance
        (broadcast against the (..., 14) bounds: a caller's margins). The law's only text
        is C (fci/limits/_joint.c ``envelope_halves``, beside the rules that read it).
        """
        q = np.asarray(q, dtype=np.float64)
        if q.ndim == 0 or q.shape[-1] != 7:
            raise ValueError(f"q: expected joint positions (..., 7), got shape {q.shape}")
        out = np.empty((*q.shape[:-1], 14))
        rows = out.reshape(-1, 14)
        if not isinstance(shift, float):
            shift = np.broadcast_to(np.asarray(shift, dtype=np.float64), rows.shape)
        constants, positional = self.joint_constants
        _envelope_law().envelope_halves(q.reshape(-1, 7), constants, positional, shift, rows)
        return out


@functools.cache
def _envelope_law():
    """The C text of the velocity envelope's law (a required extension: there is no
    other), found on first use: the module lives in fci.limits, whose rules import this
    one."""
    return native.require("fci.limits._joint", "envelope_halves")


#: FR3 behind FCI v10. Joint ranges, velocities, offsets, deceleration and
#: efforts: the URDF the robot serves (libfranka test/fr3.urdf; docs/limits.md §4).
#: Acceleration / jerk / torque rate / Cartesian / elbow: libfranka >= 0.10
#: rate_limiting.h robot values (docs/limits.md §1.1), written as the robot's
#: threshold minus kLimitEps (limit - 1e-3, docs/limits.md §1).
FR3 = RobotTable(
    name="fr3",
    fci_version=10,
    q_lower=_ro([-2.7501, -1.7918, -2.9065, -3.0481, -2.8101, 0.54092, -3.0196]),
    q_upper=_ro([2.7501, 1.7918, 2.9065, -0.1458, 2.8101, 4.5205, 3.0196]),
    dq_max=_ro([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26]),
    dq_offset=_ro([0.30, 0.20, 0.20, 0.30, 0.35, 0.35, 0.35]),
    ddq_decel=_ro([6.0, 2.585, 3.5, 4.0, 17.0, 5.5, 17.0]),
    ddq_max=_ro(np.full(7, 10.0 - LIMIT_EPS)),
    dddq_max=_ro(np.full(7, 5000.0 - LIMIT_EPS)),
    tau_max=_ro([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
    dtau_max=1000.0 - LIMIT_EPS,
    v_trans_max=3.0 - LIMIT_EPS,
    a_trans_max=9.0 - LIMIT_EPS,
    j_trans_max=4500.0 - LIMIT_EPS,
    v_rot_max=2.5 - LIMIT_EPS,
    a_rot_max=17.0 - LIMIT_EPS,
    j_rot_max=8500.0 - LIMIT_EPS,
    v_elbow_max=1.5 - LIMIT_EPS,
    a_elbow_max=10.0 - LIMIT_EPS,
    j_elbow_max=5000.0 - LIMIT_EPS,
    # docs/fci-behaviour.md "The joint side of a Cartesian command": FR3 uniform 10 rad/s^2 /
    # 5000 rad/s^3 (libfranka >= 0.10), calibration factor 1.0.
    ik_ddq_max=_ro(np.full(7, 10.0)),
    ik_dddq_max=_ro(np.full(7, 5000.0)),
)

#: FER ("Panda") behind FCI v5: Franka docs control-parameters-joint-fer.csv and
#: libfranka 0.9.2 rate_limiting.h (docs/limits.md §3). Constant velocity limits.
FER = RobotTable(
    name="fer",
    fci_version=5,
    q_lower=_ro([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]),
    q_upper=_ro([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]),
    dq_max=_ro([2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100]),
    dq_offset=None,
    ddq_decel=None,
    ddq_max=_ro(np.array([15, 7.5, 10, 12.5, 15, 20, 20]) - LIMIT_EPS),
    dddq_max=_ro(np.array([7500, 3750, 5000, 6250, 7500, 10000, 10000]) - LIMIT_EPS),
    tau_max=_ro([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
    dtau_max=1000.0 - LIMIT_EPS,
    v_trans_max=1.7 - LIMIT_EPS,
    a_trans_max=13.0 - LIMIT_EPS,
    j_trans_max=6500.0 - LIMIT_EPS,
    v_rot_max=2.5 - LIMIT_EPS,
    a_rot_max=25.0 - LIMIT_EPS,
    j_rot_max=12500.0 - LIMIT_EPS,
    v_elbow_max=2.175 - LIMIT_EPS,
    a_elbow_max=10.0 - LIMIT_EPS,
    j_elbow_max=5000.0 - LIMIT_EPS,
    # docs/fci-behaviour.md "Calibration on an FER" (FCI v5): libfranka 0.9 per-joint tables, factor
    # 1.0.
    ik_ddq_max=_ro([15, 7.5, 10, 12.5, 15, 20, 20]),
    ik_dddq_max=_ro([7500, 3750, 5000, 6250, 7500, 10000, 10000]),
)

ROBOTS: dict[str, RobotTable] = {"fr3": FR3, "fer": FER}


def robot_table(name: str) -> RobotTable:
    """The table for ``name`` ("fr3" or "fer"); a clear ValueError otherwise."""
    try:
        return ROBOTS[name.lower()]
    except KeyError:
        raise ValueError(f"unknown robot {name!r}: expected one of {sorted(ROBOTS)}") from None
