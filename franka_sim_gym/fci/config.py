"""Configuration of the simulated FCI controller (the switches and sim choices of
docs/fci-behaviour.md)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..sim.arm import DEFAULT_STIFFNESS
from .tables import RobotTable, robot_table


def env_flag(name: str) -> bool | None:
    """A FRANKA_SIM_* boolean environment variable: None when unset."""
    value = os.environ.get(name)
    if value is None or value.strip() == "":
        return None
    return value.strip().lower() in ("1", "true", "yes", "on")


def env_float(name: str) -> float | None:
    """A FRANKA_SIM_* float environment variable: None when unset; ValueError when malformed."""
    value = os.environ.get(name)
    if value is None or value.strip() == "":
        return None
    try:
        return float(value)
    except ValueError:
        raise ValueError(f"{name}={value!r} is not a number") from None


@dataclass
class ControllerConfig:
    """Everything the controller's behaviour depends on besides the commands it receives.

    The defaults are the socket server's (docs/fci-behaviour.md: checking always on,
    aborting opt-in). The Gymnasium env turns both enforcement switches on.
    """

    #: "fr3" (FCI v10) or "fer" (FCI v5): which robot's limit tables apply.
    robot: str = "fr3"
    #: docs/fci-behaviour.md "Checking is always on; aborting is opt-in": a motion-limit
    #: violation aborts the motion only when this is on (it is always logged).
    enforce_motion_limits: bool = False
    #: docs/fci-behaviour.md "Enabling the violation": 20 consecutive lost cycles abort only when
    #: on.
    enforce_comm_constraints: bool = False
    #: docs/fci-behaviour.md "The joint side of a Cartesian command": scales both joint-side tables.
    joint_discontinuity_scale: float = 1.0
    #: docs/fci-behaviour.md "Two deliberate departures": start-pose tolerances (sim choices).
    start_pose_tolerance: float = 0.1
    start_velocity_tolerance: float = 0.1
    cartesian_start_translation_tolerance: float = 0.05
    cartesian_start_rotation_tolerance: float = 0.1
    start_elbow_tolerance: float = 0.1
    #: docs/fci-behaviour.md "joint_velocity_violation (3)": margin on measured dq before firing.
    measured_velocity_margin: float = 0.1
    #: docs/fci-behaviour.md "self_collision_avoidance_violation (2)": monitored link distance [m].
    self_collision_distance: float = 0.05
    #: docs/fci-behaviour.md "Enabling the violation": recovery answers when |dq| < 0.005 rad/s
    #: for 50 consecutive cycles, or after 0.7 s (700 cycles) at the latest.
    recovery_velocity_threshold: float = 0.005
    recovery_settle_cycles: int = 50
    recovery_max_cycles: int = 700
    #: The internal joint servo's stiffness (SetJointImpedance changes it per robot).
    joint_stiffness: tuple[float, ...] = DEFAULT_STIFFNESS
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        robot_table(self.robot)  # a clear ValueError for an unknown robot
        if not (
            math.isfinite(self.joint_discontinuity_scale) and self.joint_discontinuity_scale > 0
        ):
            raise ValueError(
                f"joint_discontinuity_scale must be a positive number, got "
                f"{self.joint_discontinuity_scale!r}"
            )
        stiffness = np.asarray(self.joint_stiffness, dtype=float)
        if stiffness.shape != (7,) or not np.all(np.isfinite(stiffness)) or np.any(stiffness < 0):
            raise ValueError(f"joint_stiffness must be 7 finite values >= 0, got {stiffness}")

    @property
    def table(self) -> RobotTable:
        """The robot's limit table."""
        return robot_table(self.robot)

    @classmethod
    def from_environment(cls, **overrides) -> ControllerConfig:
        """The FRANKA_SIM_* variables (docs/fci-behaviour.md), with explicit overrides (CLI flags)
        winning."""
        values: dict = {}
        flag = env_flag("FRANKA_SIM_ENFORCE_MOTION_LIMITS")
        if flag is not None:
            values["enforce_motion_limits"] = flag
        flag = env_flag("FRANKA_SIM_ENFORCE_COMM_CONSTRAINTS")
        if flag is not None:
            values["enforce_comm_constraints"] = flag
        scale = env_float("FRANKA_SIM_JOINT_DISCONTINUITY_SCALE")
        if scale is not None:
            values["joint_discontinuity_scale"] = scale
        values.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**values)
