"""libfranka's client-side Cartesian command filters, batch-first: the env plays the client.

Each reproduces one piece of libfranka 0.21 (docs/limits.md §6), as
:mod:`franka_sim_gym.envs.client_filters` does for the joint and torque interfaces:

* :func:`cartesian_lowpass_filter` -- ``franka::cartesianLowpassFilter``
  (src/lowpass_filter.cpp): translation mixed like ``lowpass_filter``, orientation by
  quaternion slerp;
* :func:`limit_rate_cartesian_velocity` / :func:`limit_rate_cartesian_pose` -- the
  twist and pose overloads of ``franka::limitRate`` (src/rate_limiting.cpp), which
  limit the translational and rotational 3-vectors by their norms;
* :func:`reference_pose` -- the state's ``O_T_EE_c`` as the client reads it;

and one rule of the client's own, no libfranka piece: :func:`box_velocity_core`, the
safety box (``CommandGenerator(safety_box=...)``), which bounds the translational
velocity toward each wall of a workspace box before the rate limiter.

Poses are row-major ``(n, 4, 4)`` numpy matrices, not the column-major 16-value wire
layout (``fci.frames.from_wire`` / ``to_wire``). The public functions validate their
arguments as libfranka does (ValueError with libfranka's message) and broadcast them;
each libfranka rule's arithmetic has one text, in C (``envs/_client_filters.c``,
:mod:`franka_sim_gym.envs.client_kernel`), which the env's client calls every cycle. Its
rotations (quaternions, slerp, log, exp, the nearest rotation) are the algorithms of
:mod:`franka_sim_gym.sim.rotations`, one rotation at a time.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..fci.frames import is_homogeneous
from .client_filters import LOWPASS_DEFAULT_CUTOFF, check_cutoff, finite, lowpass_gain
from .client_kernel import NORM_EPS, ROTATION_POSE_FACTOR, RULES

__all__ = [
    "BOX_DECELERATION",
    "NORM_EPS",
    "ROTATION_POSE_FACTOR",
    "box_velocity_core",
    "cartesian_lowpass_filter",
    "limit_rate_cartesian_pose",
    "limit_rate_cartesian_velocity",
    "reference_pose",
]

#: The safety box's braking deceleration [m/s^2]: half the conservative limiter's 1.0
#: (commands.CARTESIAN_LIMITS), so the limiter behind the box follows its bound with
#: acceleration and jerk to spare. Moving toward a wall at the box's bound the TCP
#: brakes at this rate and stops at the wall: 0.3 m/s takes 9 cm, 0.05 m/s 2.5 mm.
BOX_DECELERATION = 0.5

#: src/lowpass_filter.cpp cartesianLowpassFilter.
_MSG_CARTESIAN_CUTOFF = (
    "Cartesian lowpass-filter: cutoff_frequency is zero, negative, infinite or NaN."
)
_MSG_CARTESIAN_SIGNAL = (
    "Cartesian lowpass-filter: current or past input value of the signal to be filtered is "
    "infinite or NaN."
)
#: src/rate_limiting.cpp, the twist and pose overloads of limitRate.
_MSG_TWIST = "O_dP_EE_c is infinite or NaN."
_MSG_POSE = "O_T_EE_c is infinite or NaN."
_MSG_POSE_INVALID = "O_T_EE_c is invalid transformation matrix. Has to be column major!"
_LIMIT_NAMES = ("v_max", "a_max", "j_max", "v_rot_max", "a_rot_max", "j_rot_max")


def cartesian_lowpass_filter(
    T_c: ArrayLike, T_ref: ArrayLike, cutoff: ArrayLike = LOWPASS_DEFAULT_CUTOFF
) -> np.ndarray:
    """Low-pass a commanded pose toward the reference pose, (n, 4, 4) -> (n, 4, 4).

    ``franka::cartesianLowpassFilter(kDeltaT, O_T_EE_c, reference, cutoff)``
    (src/lowpass_filter.cpp), as ``ControlLoop<CartesianPose>::convertMotion``
    applies it. With ``g = lowpass_gain(cutoff)``:

    * translation ``g * t_c + (1 - g) * t_ref``;
    * orientation: Eigen's ``Quaterniond::slerp`` from the reference's quaternion
      toward the command's with parameter ``g`` -- along the shorter arc (the
      command's quaternion is negated when the dot product is negative), linear
      in the coefficients once ``|dot| >= 1 - eps`` -- then normalised and turned
      back into a rotation matrix;
    * the bottom row is the command's (libfranka's ``Affine3d`` keeps it).

    libfranka first takes the rotation part of each pose by polar decomposition
    (``Affine3d::rotation()``); for the orthonormal blocks a valid pose carries that is
    the block itself to rounding, so the block is used as is. ``cutoff`` is a scalar or
    one per robot, (n,). This is the arithmetic only: ControlLoop skips it when
    ``cutoff >= MAX_CUTOFF_FREQUENCY``.

    Raises:
        ValueError: cutoff zero, negative or not finite; ``T_c`` or ``T_ref`` with a
            NaN or infinite entry (libfranka throws std::invalid_argument, in this order).
    """
    cutoff = check_cutoff(cutoff, _MSG_CARTESIAN_CUTOFF)
    T_c = finite("T_c", T_c, _MSG_CARTESIAN_SIGNAL)
    T_ref = finite("T_ref", T_ref, _MSG_CARTESIAN_SIGNAL)
    lead = np.broadcast_shapes(T_c.shape[:-2], T_ref.shape[:-2])
    gain = _per_pose("cutoff", np.asarray(lowpass_gain(cutoff), dtype=np.float64), lead)
    poses = [np.broadcast_to(T, (*lead, 4, 4)).reshape(-1, 4, 4) for T in (T_c, T_ref)]
    out = np.empty((*lead, 4, 4))
    RULES.cartesian_lowpass(*poses, gain.reshape(-1), out.reshape(-1, 4, 4))
    return out


def limit_rate_cartesian_velocity(
    twist_c: ArrayLike,
    twist_last: ArrayLike,
    dtwist_last: ArrayLike,
    v_max: ArrayLike,
    a_max: ArrayLike,
    j_max: ArrayLike,
    v_rot_max: ArrayLike,
    a_rot_max: ArrayLike,
    j_rot_max: ArrayLike,
) -> np.ndarray:
    """Rate-limit a commanded end-effector twist, (n, 6) -> (n, 6).

    The ``O_dP_EE_c`` overload of ``franka::limitRate`` (src/rate_limiting.cpp).
    The twist is (vx, vy, vz, wx, wy, wz); the translational half is limited with
    ``(v_max, a_max, j_max)``, the rotational half with ``(v_rot_max, a_rot_max,
    j_rot_max)``, each by the 3-vector limiter that bounds *norms* (dt = kDeltaT,
    eps = kNormEps = float64 machine epsilon)::

        jerk = ((v_c - v_last) / dt - a_last) / dt
        a    = a_last + jerk / |jerk| * min(|jerk|, J) * dt   if |jerk| > eps else a_last
        u    = a / |a|
        d    = -(u . v_last) + sqrt((u . v_last)^2 - |v_last|^2 + V^2)
        out  = v_last + u * min(|a|, min(J / A * d, A)) * dt  if |a| > eps else v_last

    ``d`` is how far ``v_last`` may move along ``u`` before leaving the ball of
    radius V. Two C++ corners are reproduced without producing NaN: for
    ``|a| <= eps`` the result is ``v_last`` exactly (libfranka computes ``u`` as
    0/0 but never uses it), and outside the ball, where the square root's
    argument can be negative, libfranka's ``std::min(|a|, NaN)`` yields ``|a|``:
    the acceleration is then only jerk-limited.

    With a last state inside the limits the output keeps ``|v| <= V`` (as
    ``J / A * dt <= 1``, a step never crosses the sphere) and ``|a| <= A``; along
    a straight line also ``|jerk| <= J``. That last bound is not guaranteed when
    the direction changes abruptly near ``|v| = V`` (the admissible acceleration
    depends on the direction) -- libfranka behaves the same. A command within
    reach (jerk <= J and far enough inside the ball that ``|a| <= J / A * d``)
    comes back unchanged up to rounding.

    Args:
        twist_c: the (filtered) twist command, (n, 6).
        twist_last, dtwist_last: the last commanded twist and its derivative
            (``state.O_dP_EE_c``, ``state.O_ddP_EE_c``).
        v_max, a_max, j_max: kMaxTranslationalVelocity / Acceleration / Jerk.
        v_rot_max, a_rot_max, j_rot_max: kMaxRotationalVelocity / Acceleration / Jerk.
            Each limit is a scalar or one per robot, (n,).

    Raises:
        ValueError: any NaN or infinite entry in the inputs (for the command,
            libfranka's message).
    """
    twist_c = finite("twist_c", twist_c, _MSG_TWIST)
    twist_last = finite("twist_last", twist_last)
    dtwist_last = finite("dtwist_last", dtwist_last)
    limits = _finite_limits(v_max, a_max, j_max, v_rot_max, a_rot_max, j_rot_max)
    twists = np.broadcast_arrays(twist_c, twist_last, dtwist_last)
    lead = twists[0].shape[:-1]
    twists = [x.reshape(-1, 6) for x in twists]
    out = np.empty((*lead, 6))
    limits = _per_pose("the limits", limits, lead, 6).reshape(-1, 6)
    RULES.limit_twist(*twists, limits, out.reshape(-1, 6))
    return out


def limit_rate_cartesian_pose(
    T_c: ArrayLike,
    T_last: ArrayLike,
    twist_last: ArrayLike,
    dtwist_last: ArrayLike,
    v_max: ArrayLike,
    a_max: ArrayLike,
    j_max: ArrayLike,
    v_rot_max: ArrayLike,
    a_rot_max: ArrayLike,
    j_rot_max: ArrayLike,
) -> np.ndarray:
    """Rate-limit a commanded pose, (n, 4, 4) -> (n, 4, 4).

    The ``O_T_EE_c`` overload of ``franka::limitRate`` (src/rate_limiting.cpp):

    1. the command is differentiated against the last pose: translation
       ``(t_c - t_last) / dt``, rotation ``log(R_c R_last^T) / dt`` (Eigen's
       ``AngleAxisd`` of the difference: axis * angle, the angle in [0, pi];
       ``sim.rotations.rotation_log``);
    2. that twist goes through :func:`limit_rate_cartesian_velocity` against
       ``twist_last`` / ``dtwist_last``, with the rotational limits scaled by
       kFactorCartesianRotationPoseInterface = 0.99 (include/franka/rate_limiting.h)
       here -- pass the robot's plain kMaxRotational* values, as ControlLoop does;
    3. the limited twist ``(v, w)`` is integrated over one cycle: ``t_last + v dt``,
       and, if ``|w| > kNormEps``, ``R = exp(w dt) @ R_last`` (Rodrigues,
       ``sim.rotations.rotation_exp``); otherwise ``R = R_last``.

    The result's bottom row is [0, 0, 0, 1]. libfranka takes each rotation block by
    polar decomposition first (``Affine3d::rotation()``); the blocks are used as they
    are here, which differs only by rounding for orthonormal blocks.

    Args:
        T_c: the (filtered) pose command.
        T_last: the filter reference -- ``state.O_T_EE_c``, or the command itself
            on the motion's first cycle (ControlLoop<CartesianPose>::convertMotion).
        twist_last, dtwist_last: ``state.O_dP_EE_c``, ``state.O_ddP_EE_c``, (n, 6).
        v_max, a_max, j_max, v_rot_max, a_rot_max, j_rot_max: as for
            :func:`limit_rate_cartesian_velocity` (rotational ones unscaled).

    Raises:
        ValueError: ``T_c`` with a NaN or infinite entry, or not a homogeneous
            transform (``fci.frames.is_homogeneous``: bottom row [0, 0, 0, 1],
            rotation rows and columns of unit norm within 1e-5) -- libfranka's
            messages, in this order; any other NaN or infinite input.
    """
    T_c = finite("T_c", T_c, _MSG_POSE)
    if not is_homogeneous(T_c.reshape(-1, 4, 4)).all():
        raise ValueError(f"T_c: {_MSG_POSE_INVALID} (libfranka throws std::invalid_argument)")
    T_last = finite("T_last", T_last)
    twist_last = finite("twist_last", twist_last)
    dtwist_last = finite("dtwist_last", dtwist_last)
    limits = _finite_limits(v_max, a_max, j_max, v_rot_max, a_rot_max, j_rot_max)
    poses, twists = np.broadcast_arrays(T_c, T_last), np.broadcast_arrays(twist_last, dtwist_last)
    lead = np.broadcast_shapes(poses[0].shape[:-2], twists[0].shape[:-1])
    poses = [np.broadcast_to(x, (*lead, 4, 4)).reshape(-1, 4, 4) for x in poses]
    twists = [np.broadcast_to(x, (*lead, 6)).reshape(-1, 6) for x in twists]
    limits = _per_pose("the limits", limits, lead, 6).reshape(-1, 6)
    out = np.empty((*lead, 4, 4))
    RULES.limit_pose(*poses, *twists, limits, out.reshape(-1, 4, 4))
    return out


def box_velocity_core(v, p, v_last, lower, upper, deceleration=BOX_DECELERATION, out=None):
    """The safety box: translational velocity commands (n, 3) bounded so that a TCP at
    ``p`` (n, 3) brakes to a stop at the walls of the box ``lower`` ... ``upper`` (3,)
    [m]; ``v_last`` (n, 3) is the last commanded velocity (the state's O_dP_EE_c).

    Each component toward a wall is at most ``sqrt(2 a d)``, d the distance to that wall
    (0 outside it), ``a`` = ``deceleration``: the speed from which braking at ``a``
    stops exactly at the wall. Components away from the walls, and inside the bound,
    pass unchanged; a TCP outside the box may move back in but not further out.

    It bounds the command that libfranka's rate limiter then shapes
    (commands.CommandGenerator applies it between the low-pass filter and the limiter),
    so the stream stays as smooth as the limiter makes it: the box brakes, it does not
    clip the position. The limiter bounds the acceleration's norm, shared by all three
    axes; so while the last commanded velocity is past an axis's bound (braking is
    due), the other axes hold their last velocity and the whole acceleration goes to
    the braking (without that, a policy swerving sideways on its way down took most of
    it and passed the floor by 1 cm). The rule is the client's (SERL's workspace box,
    Luo et al. 2024, as a velocity bound), not the robot's: no FCI check knows of it.
    """
    two_a = 2.0 * deceleration
    up = np.sqrt(two_a * np.maximum(upper - p, 0.0))
    down = np.sqrt(two_a * np.maximum(p - lower, 0.0))
    out = np.clip(v, -down, up, out=out)
    past = (v_last > up) | (v_last < -down)
    braking = past.any(axis=-1, keepdims=True)
    np.copyto(out, v_last, where=braking & ~past)
    return out


def reference_pose(O_T_EE_c: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The state's (n, 16) column-major O_T_EE_c as (n, 4, 4) row-major matrices, each
    rotation its nearest rotation (``sim.rotations.nearest_rotation``).

    The v10 state carries the pose in float32; libfranka reads it into an ``Affine3d``
    and its filters take ``rotation()``, the polar factor. Its orthonormal rotation
    keeps every pose built on it inside libfranka's ``isHomogeneousTransformation``.
    """
    wire = np.asarray(O_T_EE_c)
    if wire.dtype != np.float32:
        wire = wire.astype(np.float64, copy=False)
    if out is None:
        out = np.empty((len(wire), 4, 4))
    return RULES.reference_pose(wire, out)


def _per_pose(name: str, value: np.ndarray, lead: tuple[int, ...], *tail: int) -> np.ndarray:
    """``value`` broadcast to the poses' (or twists') leading shape ``lead`` (plus ``tail``):
    one value, or one per pose; anything that would add poses (an (n, 1) against (n,)
    poses) is a ValueError naming ``name``."""
    try:
        return np.broadcast_to(value, (*lead, *tail))
    except ValueError:
        got = np.shape(value)[: np.ndim(value) - len(tail)]
        raise ValueError(
            f"{name} must be one value or one per pose (shape {lead}), got shape {got}"
        ) from None


def _finite_limits(*limits: ArrayLike) -> np.ndarray:
    """The six limits, each through :func:`finite` in libfranka's order, side by side on
    a last axis: (6,) for scalars, (n, 6) for one per robot."""
    checked = [finite(name, value) for name, value in zip(_LIMIT_NAMES, limits, strict=True)]
    return np.stack(np.broadcast_arrays(*checked), axis=-1)
