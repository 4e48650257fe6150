"""From a policy action to one command per 1 ms cycle: the libfranka client's job.

The env plays the client between policy steps; the deploy script
(examples/deploy_pylibfranka.py) imports this same module to drive a real
libfranka client, so a policy meets the same command stream in training and on
the robot. Filters (``action_filter``):

* ``"none"`` — the action's target is held for every cycle of the step: what a
  naive controller sends (and the reason it trips reflexes);
* ``"interpolate"`` — linear interpolation from the reference at the start of
  the step to the target, across the step's cycles;
* ``"lowpass"`` — libfranka's first-order low-pass (100 Hz, Robot::control's
  default) against the state's reference;
* ``"limit_rate"`` — the low-pass followed by libfranka's rate limiter
  (Robot::control with ``limit_rate = true``), which keeps every command inside
  the robot's velocity, acceleration and jerk limits;
* ``"interpolate_limit_rate"`` — the interpolation's per-cycle target (a ramp from the
  step's starting reference), then the low-pass and the rate limiter as
  ``"limit_rate"``: the limiter alone crosses even a small change at its whole jerk,
  the ramp over the step, and the limiter still bounds what the ramp asks (docs/env.md,
  "Why the ramp").

``"joint_position_async"`` is libfranka's asynchronous joint-position control
(pylibfranka's ``AsyncPositionControlHandler``): the action's target is sent as is,
every cycle, and the robot's own generator moves toward it within the Move's maximum
velocities (docs/motion-limits.md "The asynchronous generator"), so no filter applies.

All filters read the robot's own references from the state (q_d, dq_d, ddq_d,
tau_J_d; O_T_EE_c, O_dP_EE_c, O_ddP_EE_c for the Cartesian interfaces), exactly as
libfranka's ControlLoop::convertMotion does.

The Cartesian interfaces send O_T_EE_c (pose) or O_dP_EE_c (twist) with no elbow
(``valid_elbow`` false: the elbow is free). Their rate limiter is libfranka's Cartesian
``limitRate``, run against ``cartesian_limits``: libfranka's own constants
(``"libfranka"``) keep the Cartesian derivatives legal but not the joint side — the
robot solves every pose to joint space and refuses joint accelerations over 10 rad/s^2
(errors 29 / 30: docs/fci-behaviour.md, The joint side of a Cartesian command) — so
the default, ``"conservative"``, limits the Cartesian motion to what the joint side
accepts.

``safety_box`` (Cartesian interfaces, off by default) is a rule of the client's own, not
libfranka's and not the robot's: the TCP kept inside a workspace box by a bound on the
translational velocity toward each wall, between the low-pass filter and the rate
limiter (``cartesian_filters.box_velocity_core``), so a policy pushing into the table
brakes to a stop above it through a legal command stream (SERL's workspace box, Luo
et al. 2024).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fci.frames import to_wire
from ..fci.tables import DELTA_T, FR3, JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from ..fci.wire import MoveControllerMode, MoveMotionGeneratorMode
from ..sim.rotations import rotation_exp, rotation_log
from . import client_filters as cf
from .cartesian_filters import BOX_DECELERATION, box_velocity_core
from .client_kernel import RULES

INTERFACES = (
    "joint_position",
    "joint_velocity",
    "cartesian_pose",
    "cartesian_velocity",
    "torque",
    "joint_position_async",
)
CARTESIAN = ("cartesian_pose", "cartesian_velocity")

#: The rate limiter's targets sit this far inside the robot's thresholds. The
#: robot's thresholds (kMaxJointAcceleration = 10 - 1e-3, kMaxJointJerk = 5000 - 1e-3,
#: kMaxTorqueRate = 1000 - 1e-3, the URDF envelope with libfranka's 1e-3 tolerance)
#: equal libfranka's own limiter targets, and the limiter integrates from the
#: float32 references of the v10 state while the robot differences in float64:
#: the rounding (half an ulp: 1.2e-7 rad at |q| ~ 3) reaches the jerk amplified by
#: 1/dt^3, up to ~120 rad/s^3. libfranka's 1e-3 margins cannot absorb that
#: (a comparison at the very threshold can go either way); our client keeps ~6 % inside.
LIMITER_MARGIN = {"ddq": 0.3, "dddq": 300.0, "dq": 0.01, "dtau": 2.0}
FILTERS = ("none", "interpolate", "lowpass", "limit_rate", "interpolate_limit_rate")
#: The filters that interpolate the step's target across its cycles.
INTERPOLATING = ("interpolate", "interpolate_limit_rate")
#: The filters that end in libfranka's rate limiter.
RATE_LIMITED = ("limit_rate", "interpolate_limit_rate")

#: The Cartesian rate limiter's targets: translation velocity [m/s], acceleration [m/s^2],
#: jerk [m/s^3], then rotation [rad/s, rad/s^2, rad/s^3].
CARTESIAN_LIMITS: dict[str, tuple[float, ...] | None] = {
    # libfranka's own limiter targets, include/franka/rate_limiting.h: the robot table's
    # Cartesian limits (fci/tables.py; FR3 3.0 / 9.0 / 4500 and 2.5 / 17 / 8500, each
    # minus kLimitEps), resolved per robot by the generator. A stream at these trips the
    # joint side (29 / 30) as it does on the robot: at home joint 2 moves 3.2 rad per
    # metre along x, so 9 m/s^2 asks ~29 rad/s^2 of it against the robot's 10.
    "libfranka": None,
    # What the joint side accepts across the reach workspace (measured with random
    # actions: tests/envs/test_env_cartesian.py): 1.5 m/s^2 already reached 10.4 rad/s^2 on
    # joint 4 with the arm half stretched (q4 = -1.35); 1.0 keeps a third in hand.
    "conservative": (0.5, 1.0, 200.0, 1.0, 2.0, 400.0),
}


def libfranka_cartesian_limits(table: RobotTable) -> tuple[float, ...]:
    """libfranka's Cartesian limiter targets for ``table``'s robot, in CARTESIAN_LIMITS's
    order (rate_limiting.h's kMax* values, which the robot's table holds)."""
    t = table
    return (t.v_trans_max, t.a_trans_max, t.j_trans_max, t.v_rot_max, t.a_rot_max, t.j_rot_max)


@dataclass
class ActionScale:
    """What an action of 1.0 means per interface."""

    #: joint position: target offset from the step's starting reference [rad]
    position: float = 0.1
    #: joint velocity: target velocity [rad/s]
    velocity: float = 1.0
    #: torque: target torque without gravity [Nm], per joint
    torque: tuple[float, ...] = (20.0, 20.0, 20.0, 20.0, 4.0, 4.0, 4.0)
    #: Cartesian pose: target offset from the step's starting reference O_T_EE_c [m]
    translation: float = 0.05
    #: Cartesian pose: target rotation from it, a base-frame rotation vector [rad]
    rotation: float = 0.2
    #: Cartesian velocity: target translational velocity [m/s]
    linear_velocity: float = 0.3
    #: Cartesian velocity: target angular velocity [rad/s]
    angular_velocity: float = 0.5
    #: asynchronous joint position: the Move's maximum joint velocities [rad/s] (None: the
    #: robot's nameplate velocities, libfranka's documented default)
    async_max_velocity: tuple[float, ...] | None = None


# Robot::control's default controller mode for a motion generator: kJointImpedance.
IMPEDANCE, GENERATOR = MoveControllerMode.kJointImpedance, MoveMotionGeneratorMode
#: The Move each action interface starts: (controller mode, motion generator mode).
MOVE = {
    "joint_position": (IMPEDANCE, GENERATOR.kJointPosition),
    "joint_velocity": (IMPEDANCE, GENERATOR.kJointVelocity),
    "cartesian_pose": (IMPEDANCE, GENERATOR.kCartesianPosition),
    "cartesian_velocity": (IMPEDANCE, GENERATOR.kCartesianVelocity),
    "torque": (MoveControllerMode.kExternalController, GENERATOR.kNone),
    "joint_position_async": (IMPEDANCE, GENERATOR.kJointPosition),  # + move_options
}
#: The wire field each action interface commands.
COMMAND_FIELD = {
    "joint_position": "q_c",
    "joint_velocity": "dq_c",
    "cartesian_pose": "O_T_EE_c",
    "cartesian_velocity": "O_dP_EE_c",
    "torque": "tau_J_d",
    "joint_position_async": "q_c",
}


def move_options(interface: str, table: RobotTable, scale: ActionScale | None = None) -> dict:
    """The Move's extra arguments for ``interface`` (``FciController.move`` keywords): the
    asynchronous flag and maximum velocities for ``"joint_position_async"``, else none."""
    if interface != "joint_position_async":
        return {}
    caps = (scale or ActionScale()).async_max_velocity
    caps = tuple(table.dq_max) if caps is None else tuple(float(v) for v in caps)
    return {"use_async_motion_generator": True, "maximum_velocity": caps}


class CommandGenerator:
    """Turns one action per policy step into one command per cycle, for n robots.

    Args:
        interface: one of ``INTERFACES``.
        action_filter: one of ``FILTERS``.
        cycles_per_step: cycles between two policy actions.
        table: the robot whose limits the rate limiter uses (libfranka's own).
        scale: the meaning of a unit action.
        cutoff: the low-pass filter's cutoff frequency [Hz].
        n: how many robots (the leading axis of actions, states and commands).
        cartesian_dof: Cartesian interfaces: 6 (translation and rotation) or 3
            (translation; the orientation is held where the motion started).
        cartesian_limits: the Cartesian rate limiter's targets, a key of
            ``CARTESIAN_LIMITS`` or six numbers.
        safety_box: None (default), or the TCP's workspace box as two corners
            ``((x, y, z) lowest, (x, y, z) highest)`` in the base frame [m]: the
            translational command toward each wall is bounded so that the TCP brakes
            at ``cartesian_filters.BOX_DECELERATION`` to a stop at the wall (the
            measured O_T_EE under the twist interface, whose O_T_EE_c the robot does
            not update; the commanded O_T_EE_c under the pose interface). Cartesian
            interfaces with the ``"lowpass"``, ``"limit_rate"`` or
            ``"interpolate_limit_rate"`` filter only.
    """

    def __init__(
        self,
        interface: str,
        action_filter: str,
        cycles_per_step: int,
        table: RobotTable = FR3,
        scale: ActionScale | None = None,
        cutoff: float = cf.LOWPASS_DEFAULT_CUTOFF,
        n: int = 1,
        cartesian_dof: int = 6,
        cartesian_limits: str | tuple[float, ...] = "conservative",
        safety_box=None,
    ) -> None:
        if interface not in INTERFACES:
            raise ValueError(f"unknown action interface {interface!r}: expected {INTERFACES}")
        if action_filter not in FILTERS:
            raise ValueError(f"unknown action_filter {action_filter!r}: expected {FILTERS}")
        if cartesian_dof not in (3, 6):
            raise ValueError(f"cartesian_dof must be 3 or 6, got {cartesian_dof!r}")
        if cartesian_limits == "libfranka":
            limits = libfranka_cartesian_limits(table)
        elif isinstance(cartesian_limits, str):
            limits = CARTESIAN_LIMITS.get(cartesian_limits, cartesian_limits)
        else:  # six numbers (a JSON list works too)
            limits = tuple(cartesian_limits)
        if isinstance(limits, str) or len(limits) != 6 or not all(float(x) > 0 for x in limits):
            raise ValueError(
                f"cartesian_limits must be one of {tuple(CARTESIAN_LIMITS)} or six positive "
                f"numbers, got {cartesian_limits!r}"
            )
        self.safety_box = check_safety_box(safety_box, interface, action_filter)
        self.interface = interface
        self.cartesian_dof = int(cartesian_dof)
        self.cartesian_limits = tuple(float(x) for x in limits)
        self.action_filter = action_filter
        self.cycles_per_step = cycles_per_step
        self.table = table
        self.scale = scale or ActionScale()
        self.cutoff = cutoff
        # Validated once here; every cycle runs the rules' one text (client_kernel.RULES:
        # envs/_client_filters.c), which takes a value per robot (and per joint): the
        # gains and limits below are broadcast views of one value, made once.
        gain = np.asarray(cf.lowpass_gain(cutoff), dtype=np.float64).reshape(-1)
        if gain.size not in (1, n):
            raise ValueError(f"cutoff must be one value or one per arm ({n}), got {cutoff!r}")
        cols = 6 if interface == "cartesian_velocity" else 7
        self._pose_gain = np.broadcast_to(gain, (n,))
        self._gain = np.broadcast_to(self._pose_gain[:, None], (n, cols))
        m = LIMITER_MARGIN
        self._ddq_max = np.broadcast_to(table.ddq_max - m["ddq"], (n, 7))
        self._dddq_max = np.broadcast_to(table.dddq_max - m["dddq"], (n, 7))
        self._dtau_max = np.broadcast_to(table.dtau_max - m["dtau"], (n, 7))
        self._limits = np.broadcast_to(np.asarray(self.cartesian_limits), (n, 6))
        self._band_shift = JOINT_VELOCITY_LIMIT_TOLERANCE + m["dq"]
        self._lowpassed = np.zeros((n, cols))
        self._out = np.zeros_like(self._lowpassed)
        self._fields_of = None
        self._joint_client_fields = None  # the fields the joint cycle's plan was made over
        self._joint_client_plan = None
        self._field_views: dict[str, np.ndarray] = {}
        self._ref_pose = np.zeros((n, 4, 4))
        self._pose_lowpassed = np.zeros((n, 4, 4))
        self._pose_out = np.zeros((n, 4, 4))
        # A unit twist action's twist, per component.
        self._twist_scale = np.repeat([self.scale.linear_velocity, self.scale.angular_velocity], 3)
        self._start = None
        self._target = None
        self._turn = None
        #: per robot: its motion's first command is still to be sent (no reference yet)
        self._first = np.ones(n, dtype=bool)
        self._n_first = n

    @property
    def action_dim(self) -> int:
        """The length of one robot's action."""
        return self.cartesian_dof if self.interface in CARTESIAN else 7

    def reset(self, robots: np.ndarray | None = None) -> None:
        """New motions for ``robots`` (all when None): their first command is not filtered
        against a reference."""
        self._first[slice(None) if robots is None else robots] = True
        self._n_first = int(np.count_nonzero(self._first))

    def begin_step(self, action: np.ndarray, state: np.ndarray) -> None:
        """Fix the step's target from the action (n, action_dim) in [-1, 1] and the state."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        if self.interface in CARTESIAN:
            self._begin_cartesian(a, state)
        elif self.interface in ("joint_position", "joint_position_async"):
            self._start = state["q_d"].astype(np.float64)
            self._target = self._start + a * self.scale.position
        elif self.interface == "joint_velocity":
            self._start = state["dq_d"].astype(np.float64)
            self._target = a * self.scale.velocity
        else:
            self._start = state["tau_J_d"].astype(np.float64)
            self._target = a * np.asarray(self.scale.torque)
        if self.action_filter in INTERPOLATING:
            # The step's ends, checked once as interpolate checks them (a non-finite
            # state raises its error here); every cycle then takes interpolate_core.
            if self.interface == "cartesian_pose":
                cf.interpolate(self._start[:, :3, 3], self._target[:, :3, 3], 1.0)
            else:
                cf.interpolate(self._start, self._target, 1.0)

    def command(self, state: np.ndarray, k: int, sent: np.ndarray | None = None) -> np.ndarray:
        """Cycle ``k``'s (0-based) command (valid until the next call), given the newest
        state: (n, 7) joint values or torques, (n, 16) column-major O_T_EE_c, or (n, 6)
        O_dP_EE_c.

        ``sent`` marks the robots whose command is actually sent this cycle (None: all);
        a robot's first-command status ends only with a command sent.
        """
        if self.interface == "cartesian_pose":
            out = self._pose_wire(state, k)
        elif self.action_filter == "none" or self.interface == "joint_position_async":
            out = self._target
        elif self.action_filter == "interpolate":  # (its ends checked in begin_step)
            out = cf.interpolate_core(self._start, self._target, self._phase(k))
        else:
            out = self._filtered(state, k)
        if self._n_first:
            if sent is None:
                self._first[...] = False
            else:
                self._first &= ~sent
            self._n_first = int(np.count_nonzero(self._first))
        return out

    def _phase(self, k: int) -> float:
        """Cycle k's (0-based) fraction of the step: the interpolation reaches the target
        at the step's last cycle."""
        return (k + 1) / self.cycles_per_step

    def _begin_cartesian(self, a: np.ndarray, state: np.ndarray) -> None:
        six = np.zeros((len(a), 6))
        six[:, : self.cartesian_dof] = a
        sc = self.scale
        if self.interface == "cartesian_velocity":
            self._start = state["O_dP_EE_c"].astype(np.float64)
            self._target = six * self._twist_scale
            return
        T = RULES.reference_pose(state["O_T_EE_c"], np.empty((len(a), 4, 4)))
        target = T.copy()
        target[:, :3, 3] += six[:, :3] * sc.translation
        target[:, :3, :3] = rotation_exp(six[:, 3:] * sc.rotation) @ T[:, :3, :3]
        self._start, self._target = T, target
        if self.action_filter in INTERPOLATING:  # the step's rotation, interpolated per cycle
            self._turn = rotation_log(target[:, :3, :3] @ T[:, :3, :3].transpose(0, 2, 1))

    def _pose_wire(self, state: np.ndarray, k: int) -> np.ndarray:
        """Cycle k's O_T_EE_c in the wire's column-major layout, (n, 16)."""
        return to_wire(self._pose_command(state, k))

    def _pose_command(self, state: np.ndarray, k: int) -> np.ndarray:
        """Cycle k's O_T_EE_c as (n, 4, 4) matrices."""
        start, target = self._start, self._target
        if self.action_filter == "none":
            return target
        if self.action_filter in INTERPOLATING:
            s = self._phase(k)
            ramp = target.copy()
            ramp[:, :3, 3] = cf.interpolate_core(start[:, :3, 3], target[:, :3, 3], s)
            ramp[:, :3, :3] = rotation_exp(s * self._turn) @ start[:, :3, :3]
            if self.action_filter == "interpolate":
                return ramp
            target = ramp
        ref = RULES.reference_pose(state["O_T_EE_c"], self._ref_pose)
        out = RULES.cartesian_lowpass(target, ref, self._pose_gain, self._pose_lowpassed)
        if self.safety_box is not None:  # the step from the commanded pose, as a velocity
            t_ref, t = ref[:, :3, 3], out[:, :3, 3]
            v_last = state["O_dP_EE_c"][:, :3]
            v = box_velocity_core((t - t_ref) / DELTA_T, t_ref, v_last, *self.safety_box)
            t[...] = t_ref + v * DELTA_T
        if self.action_filter not in RATE_LIMITED:
            return out
        twist = (state["O_dP_EE_c"], state["O_ddP_EE_c"])
        return RULES.limit_pose(out, ref, *twist, self._limits, self._pose_out)

    def _fields(self, state: np.ndarray) -> dict[str, np.ndarray]:
        """The state's fields the filters read, as views made once per state array (the
        controller publishes into the same array every cycle)."""
        if state is not self._fields_of:
            names = ("q_d", "dq_d", "ddq_d", "tau_J_d", "O_dP_EE_c", "O_ddP_EE_c")
            self._field_views = {name: state[name] for name in names}
            self._fields_of = state
        return self._field_views

    def _joint_client(self, fields: dict[str, np.ndarray]):
        """The joint cycle's C plan over the state's fields ``fields`` (made once per state
        array, as the fields' views are: envs/_client_filters.c JointClient)."""
        if fields is not self._joint_client_fields:
            self._joint_client_plan = RULES.JointClient(
                self.interface == "joint_position",
                self.action_filter in RATE_LIMITED,
                fields["q_d"],
                fields["dq_d"],
                fields["ddq_d"],
                self._gain,
                *self.table.joint_constants,
                self._band_shift,
                self._ddq_max,
                self._dddq_max,
                self._out,
            )
            self._joint_client_fields = fields
        return self._joint_client_plan

    def _filtered(self, state: np.ndarray, k: int) -> np.ndarray:
        """Cycle k's joint, torque or twist command: libfranka's low-pass filter against
        the state's reference, then (``"limit_rate"``) its rate limiter; with
        ``"interpolate_limit_rate"``, of the interpolation's target for cycle k."""
        target, interface = self._target, self.interface
        if self.action_filter == "interpolate_limit_rate":
            target = cf.interpolate_core(self._start, target, self._phase(k))
        fields = self._fields(state)
        if interface in ("joint_position", "joint_velocity"):
            # libfranka's low-pass (a position motion's first command its own reference:
            # no q_d to filter to), then ("limit_rate") its limiter inside the velocity
            # band at the last commanded position (libfranka evaluates it at the
            # reference) with the client's margin inside libfranka's tolerance: one C
            # call (envs/_client_filters.c JointClient, planned once per state array)
            return self._joint_client(fields).cycle(target, self._first if self._n_first else None)
        # The twist's and the torque's: the low-pass, then ("limit_rate") their limiters.
        x = RULES.lowpass(target, fields[_REFERENCE[interface]], self._gain, self._lowpassed)
        if self.safety_box is not None:  # (the twist interface: box set, see __init__)
            p = state["O_T_EE"][:, 12:15]  # measured: O_T_EE_c stays at the motion's start
            v_last = fields["O_dP_EE_c"][:, :3]
            box_velocity_core(x[:, :3], p, v_last, *self.safety_box, out=x[:, :3])
        if self.action_filter not in RATE_LIMITED:
            return x
        out = self._out
        if interface == "cartesian_velocity":
            twist = (fields["O_dP_EE_c"], fields["O_ddP_EE_c"])
            return RULES.limit_twist(x, *twist, self._limits, out)
        return RULES.limit_torques(x, fields["tau_J_d"], self._dtau_max, out)


def check_safety_box(box, interface: str, action_filter: str):
    """``box`` as ``(lower (3,), upper (3,), deceleration)`` floats, or None; a ValueError
    names what is wrong (not two finite corners with lower < upper, an interface or a
    filter the box cannot bound)."""
    if box is None:
        return None
    try:
        corners = np.asarray(box, dtype=np.float64)
    except (TypeError, ValueError):
        corners = None
    if corners is None or corners.shape != (2, 3) or not np.isfinite(corners).all():
        raise ValueError(
            f"safety_box must be two corners ((x, y, z), (x, y, z)) in metres, got {box!r}"
        )
    lower, upper = corners
    if not (lower < upper).all():
        raise ValueError(f"safety_box: each lower corner value must be below the upper: {box!r}")
    if interface not in CARTESIAN:
        raise ValueError(f"safety_box bounds the Cartesian interfaces, not {interface!r}")
    if action_filter not in ("lowpass", *RATE_LIMITED):
        raise ValueError(
            "safety_box needs action_filter 'limit_rate' (or 'lowpass', "
            "'interpolate_limit_rate'): it bounds the "
            f"per-cycle velocity, which {action_filter!r} does not shape"
        )
    return lower, upper, BOX_DECELERATION


#: The state field each interface's filters run against (libfranka's ControlLoop).
_REFERENCE = {
    "torque": "tau_J_d",
    "cartesian_velocity": "O_dP_EE_c",
}
