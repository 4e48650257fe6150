"""libfranka's client-side command filters, batch-first: the env plays the client.

Pure functions over float64 arrays with a leading robot axis, ``(n, 7)``; any
shapes that broadcast work the same. Each reproduces one piece of libfranka
0.21 (shared/spec/limits.md §6) operation for operation, so that a command
stream built here equals the one a ``franka::Robot::control(...)`` loop sends:

* :func:`lowpass_filter` -- ``franka::lowpassFilter`` (include/franka/lowpass_filter.h,
  src/lowpass_filter.cpp), with the gain of :func:`lowpass_gain`;
* :func:`limit_rate_joint_velocities` / :func:`limit_rate_joint_positions` -- the
  scalar velocity and position overloads of ``franka::limitRate``
  (src/rate_limiting.cpp), vectorised over robots and joints;
* :func:`limit_rate_torques` -- the ``limitRate(max_derivatives, commanded,
  last_commanded)`` overload used for torques;
* :func:`cartesian_lowpass_filter` -- ``franka::cartesianLowpassFilter``
  (src/lowpass_filter.cpp): translation mixed like :func:`lowpass_filter`,
  orientation by quaternion slerp;
* :func:`limit_rate_cartesian_velocity` / :func:`limit_rate_cartesian_pose` -- the
  twist and pose overloads of ``franka::limitRate`` (src/rate_limiting.cpp), which
  limit the translational and rotational 3-vectors by their norms.

None of them decides *whether* to filter: ``ControlLoop`` filters only when
``cutoff_frequency < kMaxCutoffFrequency`` (:data:`MAX_CUTOFF_FREQUENCY`) and
rate-limits only when ``limit_rate`` is true (default false since 0.10.0). The
caller passes the robot's own references from the state, exactly as
``ControlLoop<T>::convertMotion`` / ``spinControl`` (src/control_loop.cpp) do,
in the order callback -> low-pass -> rate limiter -> finite check -> send::

    # JointPositions: reference = the command itself on the motion's first
    # cycle (initialized_filter_ false), state.q_d afterwards; the limiter's
    # velocity bounds are evaluated at that reference, its last position is it.
    ref = q_c if first_cycle else state.q_d
    if cutoff < MAX_CUTOFF_FREQUENCY:
        q_c = lowpass_filter(q_c, ref, cutoff)
    if limit_rate:
        upper, lower = table.velocity_envelope(ref)
        q_c = limit_rate_joint_positions(q_c, ref, state.dq_d, state.ddq_d,
                                         upper, lower, table.ddq_max, table.dddq_max)

    # JointVelocities: reference state.dq_d (also on the first cycle); bounds at state.q_d.
    dq_c = lowpass_filter(dq_c, state.dq_d, cutoff)
    upper, lower = table.velocity_envelope(state.q_d)
    dq_c = limit_rate_joint_velocities(dq_c, state.dq_d, state.ddq_d,
                                       upper, lower, table.ddq_max, table.dddq_max)

    # Torques: reference state.tau_J_d.
    tau = lowpass_filter(tau, state.tau_J_d, cutoff)
    tau = limit_rate_torques(tau, state.tau_J_d, table.dtau_max)

    # CartesianPose (row-major (n, 4, 4); the wire is column-major -- frames.from_wire):
    # reference = the command on the first cycle, state.O_T_EE_c afterwards.
    ref = T_c if first_cycle else state.O_T_EE_c
    T_c = cartesian_lowpass_filter(T_c, ref, cutoff)
    T_c = limit_rate_cartesian_pose(T_c, ref, state.O_dP_EE_c, state.O_ddP_EE_c,
                                    table.v_trans_max, table.a_trans_max, table.j_trans_max,
                                    table.v_rot_max, table.a_rot_max, table.j_rot_max)

    # CartesianVelocities: per-component lowpass_filter against state.O_dP_EE_c.
    dP_c = lowpass_filter(dP_c, state.O_dP_EE_c, cutoff)
    dP_c = limit_rate_cartesian_velocity(dP_c, state.O_dP_EE_c, state.O_ddP_EE_c,
                                         table.v_trans_max, ..., table.j_rot_max)

The limiter targets are libfranka's ``rate_limiting.h`` constants (robot limit
minus kLimitEps = 1e-3): for the FR3 these are the table's ``ddq_max`` /
``dddq_max`` / ``dtau_max`` and ``v/a/j_trans_max``, ``v/a/j_rot_max`` (kMaxTranslational*,
kMaxRotational*), and ``RobotTable.velocity_envelope`` is exactly
``Robot::getUpper/LowerJointVelocityLimits`` (tolerance included).

Where libfranka throws ``std::invalid_argument`` (non-finite values, a cutoff
that is not a positive finite number) these functions raise :class:`ValueError`
with libfranka's message, prefixed by the offending argument.

:func:`interpolate` is not libfranka: it is the plain per-cycle interpolation
of the env's ``"interpolate"`` action filter.
"""

from __future__ import annotations

import math

import numpy as np
from numpy import count_nonzero
from numpy.typing import ArrayLike

from ..fci.frames import is_homogeneous
from ..fci.tables import DELTA_T, INTERIOR_SPEED, JOINT_VELOCITY_LIMIT_TOLERANCE, RobotTable
from ..sim.kinematics import skew

__all__ = [
    "DELTA_T",
    "LOWPASS_DEFAULT_CUTOFF",
    "MAX_CUTOFF_FREQUENCY",
    "cartesian_lowpass_filter",
    "interpolate",
    "limit_rate_cartesian_pose",
    "limit_rate_cartesian_velocity",
    "limit_rate_joint_positions",
    "limit_rate_joint_velocities",
    "limit_rate_torques",
    "lowpass_filter",
    "lowpass_gain",
]

#: include/franka/lowpass_filter.h: kDefaultCutoffFrequency [Hz], Robot::control's default.
LOWPASS_DEFAULT_CUTOFF = 100.0
#: include/franka/lowpass_filter.h: kMaxCutoffFrequency [Hz]. ControlLoop filters only
#: when cutoff_frequency < this value; at or above it the command passes unfiltered.
MAX_CUTOFF_FREQUENCY = 1000.0

#: src/control_data_checker.cpp checkFinite / src/rate_limiting.cpp.
_MSG_COMMAND = "Commanding value is infinite or NaN."
#: src/lowpass_filter.cpp (libfranka >= 0.8).
_MSG_CUTOFF = "lowpass-filter: cutoff_frequency is zero, negative, infinite or NaN."
_MSG_SAMPLE_TIME = "lowpass-filter: sample_time is negative, infinite or NaN."
_MSG_SIGNAL = (
    "lowpass-filter: current or past input value of the signal to be filtered is infinite or NaN."
)

_INTERPOLATION_KINDS = ("linear", "cosine")

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

#: include/franka/rate_limiting.h kNormEps: below this norm a Cartesian jerk,
#: acceleration or angular velocity counts as zero.
_NORM_EPS = float(np.finfo(np.float64).eps)
#: include/franka/rate_limiting.h kFactorCartesianRotationPoseInterface: the pose
#: overload of limitRate scales the rotational limits by this factor.
_ROTATION_POSE_FACTOR = 0.99
#: Eigen's QuaternionBase::slerp interpolates linearly once |dot| >= 1 - epsilon.
_SLERP_LINEAR = 1.0 - _NORM_EPS


def _finite(name: str, value: ArrayLike, message: str | None = None) -> np.ndarray:
    """``value`` as float64; ValueError naming ``name`` if any entry is NaN or infinite.

    ``message`` is libfranka's own where libfranka checks this very value (and
    throws std::invalid_argument); references and limits, which libfranka does
    not check up front (a NaN there only surfaces in the final checkFinite of the
    command), get a plain message.
    """
    array = np.asarray(value, dtype=np.float64)
    # count_nonzero is numpy's C call (no reduce machinery): this runs ~10 times a cycle.
    if count_nonzero(np.isfinite(array)) != array.size:
        if message is None:
            raise ValueError(f"{name} contains NaN or infinite entries")
        raise ValueError(f"{name}: {message} (libfranka throws std::invalid_argument)")
    return array


def _check_cutoff(cutoff: ArrayLike, message: str = _MSG_CUTOFF) -> np.ndarray:
    c = np.asarray(cutoff, dtype=np.float64)
    if not (np.isfinite(c).all() and (c > 0.0).all()):
        raise ValueError(f"cutoff={cutoff!r}: {message} (libfranka throws std::invalid_argument)")
    return c


def lowpass_gain(cutoff: ArrayLike, dt: float = DELTA_T) -> float | np.ndarray:
    """The first-order low-pass gain ``dt / (dt + 1/(2 pi fc))``.

    src/lowpass_filter.cpp ``lowpassFilter``; ControlLoop always passes
    ``dt = kDeltaT = 1e-3`` (not the measured time step). 0.385870 at 100 Hz.
    Raises ValueError where libfranka throws: cutoff not a positive finite
    number, or dt negative or not finite.
    """
    if not (math.isfinite(dt) and dt >= 0.0):
        raise ValueError(f"dt={dt!r}: {_MSG_SAMPLE_TIME} (libfranka throws std::invalid_argument)")
    c = _check_cutoff(cutoff)
    gain = dt / (dt + (1.0 / (2.0 * math.pi * c)))
    return float(gain) if gain.ndim == 0 else gain


def lowpass_filter(
    x: ArrayLike, x_ref: ArrayLike, cutoff: ArrayLike = LOWPASS_DEFAULT_CUTOFF
) -> np.ndarray:
    """``g * x + (1 - g) * x_ref`` with ``g = lowpass_gain(cutoff)``, elementwise.

    ``franka::lowpassFilter(kDeltaT, x, x_ref, cutoff)`` (src/lowpass_filter.cpp),
    as ControlLoop applies it per joint. ``x`` is the callback's command, ``x_ref``
    the state's reference (q_d / dq_d / tau_J_d, or the command itself on a
    position motion's first cycle). This is the filter's arithmetic only: libfranka
    does not call it at all when ``cutoff >= MAX_CUTOFF_FREQUENCY`` -- the caller
    decides. ``cutoff`` may be a scalar or broadcast against ``x`` (e.g. (n, 1)).
    Like libfranka's, the result for ``x == x_ref`` is ``x`` only to 1 ulp.

    Raises:
        ValueError: cutoff zero, negative or not finite; ``x`` or ``x_ref`` with a
            NaN or infinite entry (libfranka throws std::invalid_argument, in this order).
    """
    gain = lowpass_gain(cutoff)
    x = _finite("x", x, _MSG_SIGNAL)
    x_ref = _finite("x_ref", x_ref, _MSG_SIGNAL)
    return lowpass_core(x, x_ref, gain)


# -- the filters' arithmetic on validated inputs -------------------------------------------
# The public functions above and below validate every argument, as libfranka does, on
# every call. A caller that validated its inputs once (the env: a finite action, a
# checked cutoff and constant limits; the states are the controller's own) calls these
# cores per cycle instead -- the same arithmetic, without ~10 array checks a cycle.


def lowpass_core(x: np.ndarray, x_ref: np.ndarray, gain) -> np.ndarray:
    """:func:`lowpass_filter`'s arithmetic: float64 arrays, ``gain`` from :func:`lowpass_gain`."""
    return gain * x + (1.0 - gain) * x_ref


def limit_positions_core(q_c, q_last, v_last, a_last, upper, lower, a_max, j_max) -> np.ndarray:
    """:func:`limit_rate_joint_positions`'s arithmetic on validated float64 arrays (no
    band: as :func:`limit_velocities_core`)."""
    v = limit_velocities_core((q_c - q_last) / DELTA_T, v_last, a_last, upper, lower, a_max, j_max)
    return q_last + v * DELTA_T


def limit_torques_core(tau_c, tau_last, d_max) -> np.ndarray:
    """:func:`limit_rate_torques`'s arithmetic on validated float64 arrays."""
    rate = (tau_c - tau_last) / DELTA_T
    return tau_last + np.maximum(np.minimum(rate, d_max), -d_max) * DELTA_T


def limit_rate_joint_velocities(
    dq_c: ArrayLike,
    dq_last: ArrayLike,
    ddq_last: ArrayLike,
    upper: ArrayLike,
    lower: ArrayLike,
    ddq_max: ArrayLike,
    dddq_max: ArrayLike,
) -> np.ndarray:
    """Rate-limit commanded joint velocities, (n, 7) -> (n, 7).

    The scalar ``franka::limitRate(upper, lower, max_acceleration, max_jerk,
    commanded_velocity, last_commanded_velocity, last_commanded_acceleration)``
    of src/rate_limiting.cpp (libfranka >= 0.11, limits.md §6.3), per joint,
    vectorised; with dt = kDeltaT::

        jerk = ((dq_c - dq_last) / dt - ddq_last) / dt
        acc  = ddq_last + clamp(jerk, -J, J) * dt
        hi   = min(J / A * (upper - dq_last),  A)
        lo   = max(J / A * (lower - dq_last), -A)
        out  = dq_last + max(min(acc, hi), lo) * dt

    The clamp order is libfranka's: if ``lo > hi`` (the last velocity already
    far outside the band) the lower bound wins.

    With bounds that stay constant and a last state inside them, the output keeps
    ``lower <= v <= upper``, ``|a| <= A`` and ``|jerk| <= J`` (the band shrinks
    the admissible acceleration by J dt per cycle at most, since J dt <= A). With
    the position-based envelope, which moves with q, that is not guaranteed:
    heading into a joint limit the velocity can lag the shrinking envelope and
    the jerk exceed J -- libfranka behaves the same; nothing here corrects it.

    Args:
        dq_c: the (filtered) velocity command.
        dq_last, ddq_last: the last commanded velocity and acceleration
            (``state.dq_d``, ``state.ddq_d``).
        upper, lower: the velocity bounds, (n, 7) -- ``velocity_envelope(state.q_d)``.
        ddq_max, dddq_max: ``kMaxJointAcceleration`` / ``kMaxJointJerk`` (A, J),
            broadcast against the rest (e.g. (7,)).

    Raises:
        ValueError: any NaN or infinite entry in the inputs (libfranka checks the
            command up front and the result before sending).
    """
    dq_c = _finite("dq_c", dq_c, _MSG_COMMAND)
    v_last = _finite("dq_last", dq_last)
    a_last = _finite("ddq_last", ddq_last)
    upper = _finite("upper", upper)
    lower = _finite("lower", lower)
    a_max = _finite("ddq_max", ddq_max)
    j_max = _finite("dddq_max", dddq_max)
    return limit_velocities_core(dq_c, v_last, a_last, upper, lower, a_max, j_max)


def limit_velocities_core(v_c, v_last, a_last, upper, lower, a_max, j_max) -> np.ndarray:
    """The scalar velocity limiter of src/rate_limiting.cpp, on validated float64 arrays.

    ``upper`` and ``lower`` None: the band is far from ``v_last``, so that both
    acceleration bounds are at +-A (``J / A * (upper - v_last) >= A`` and the mirror)
    and ``min(., A)`` / ``max(., -A)`` return A and -A exactly; the caller proves that
    (:class:`FarFromTheBand`). The result is then the very bits the band would give.
    """
    dt = DELTA_T
    # Differentiate to get jerk.
    jerk = (((v_c - v_last) / dt) - a_last) / dt
    # Limit jerk and integrate to get acceleration.
    acc = a_last + np.maximum(np.minimum(jerk, j_max), -j_max) * dt
    # Compute acceleration limits.
    if upper is None:
        safe_max, safe_min = a_max, -a_max
    else:
        ratio = j_max / a_max
        safe_max = np.minimum(ratio * (upper - v_last), a_max)
        safe_min = np.maximum(ratio * (lower - v_last), -a_max)
    # Limit acceleration and integrate to get the velocity.
    return v_last + np.maximum(np.minimum(acc, safe_max), safe_min) * dt


class FarFromTheBand:
    """Decides, on one comparison, that libfranka's velocity limiter cannot meet its
    position-based velocity band this cycle, so that its envelope need not be computed
    (:func:`limit_velocities_core` with no band).

    The limiter's acceleration bounds are ``min(J / A * (upper(q) - v_last), A)`` and the
    mirror; they are exactly +-A whenever ``v_last`` is at least A^2 / J inside the band.
    Inside the joint ranges' interior (:meth:`RobotTable.interior_bounds`) the band is
    at least its value at the interior's edge; twice A^2 / J inside that (for the
    rounding) proves both bounds saturated, on [q | v_last | -q | -v_last].

    Args:
        table: the robot's limits.
        a_max, j_max: the limiter's A and J per joint.
        margin: subtracted from the band (libfranka's kLimitEps-style margin).
    """

    def __init__(
        self, table: RobotTable, a_max: np.ndarray, j_max: np.ndarray, margin: float
    ) -> None:
        inside = table.interior_bounds(INTERIOR_SPEED, JOINT_VELOCITY_LIMIT_TOLERANCE)
        reach = 2.0 * np.asarray(a_max) ** 2 / np.asarray(j_max)
        upper, lower = inside[:7] - margin, inside[14:21] - margin  # as the limiter's order
        self.bounds = np.concatenate([inside[7:14], upper - reach, inside[21:], lower - reach])
        self._x = np.zeros((0, 28))

    def __call__(self, q: np.ndarray, v_last: np.ndarray) -> bool:
        """True when every robot's limiter is saturated at +-A this cycle ((n, 7) each)."""
        x = self._x
        if x.shape[0] != len(q):
            x = self._x = np.zeros((len(q), 28))
        x[:, :7] = q
        x[:, 7:14] = v_last
        np.negative(x[:, :14], out=x[:, 14:])
        return count_nonzero(x <= self.bounds) == x.size


def limit_rate_joint_positions(
    q_c: ArrayLike,
    q_last: ArrayLike,
    dq_last: ArrayLike,
    ddq_last: ArrayLike,
    upper: ArrayLike,
    lower: ArrayLike,
    ddq_max: ArrayLike,
    dddq_max: ArrayLike,
) -> np.ndarray:
    """Rate-limit commanded joint positions, (n, 7) -> (n, 7).

    The scalar position ``franka::limitRate`` of src/rate_limiting.cpp: the
    command is differentiated against the last position, ``(q_c - q_last) / dt``,
    passed through the velocity limiter of :func:`limit_rate_joint_velocities`
    with ``dq_last`` / ``ddq_last``, and re-integrated: ``q_last + v * dt``.

    Args:
        q_c: the (filtered) position command.
        q_last: the filter reference -- ``state.q_d``, or the command itself on
            the motion's first cycle (ControlLoop<JointPositions>::convertMotion).
        dq_last, ddq_last: ``state.dq_d``, ``state.ddq_d``.
        upper, lower: the velocity bounds, (n, 7) -- ``velocity_envelope(q_last)``
            (libfranka evaluates them at the reference, not at measured q).
        ddq_max, dddq_max: ``kMaxJointAcceleration`` / ``kMaxJointJerk``.

    Raises:
        ValueError: any NaN or infinite entry in the inputs.
    """
    q_c = _finite("q_c", q_c, _MSG_COMMAND)
    q_last = _finite("q_last", q_last)
    v_last = _finite("dq_last", dq_last)
    a_last = _finite("ddq_last", ddq_last)
    upper = _finite("upper", upper)
    lower = _finite("lower", lower)
    a_max = _finite("ddq_max", ddq_max)
    j_max = _finite("dddq_max", dddq_max)
    return limit_positions_core(q_c, q_last, v_last, a_last, upper, lower, a_max, j_max)


def limit_rate_torques(tau_c: ArrayLike, tau_last: ArrayLike, dtau_max: ArrayLike) -> np.ndarray:
    """Rate-limit commanded torques, (n, 7) -> (n, 7).

    ``franka::limitRate(kMaxTorqueRate, tau_c, state.tau_J_d)`` (the
    ``max_derivatives`` overload of src/rate_limiting.cpp)::

        out = tau_last + clamp((tau_c - tau_last) / dt, -dtau_max, dtau_max) * dt

    Raises:
        ValueError: any NaN or infinite entry in the inputs.
    """
    tau_c = _finite("tau_c", tau_c, _MSG_COMMAND)
    tau_last = _finite("tau_last", tau_last)
    d_max = _finite("dtau_max", dtau_max)
    return limit_torques_core(tau_c, tau_last, d_max)


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

    Poses are row-major numpy matrices, not the column-major 16-value wire layout
    (convert with ``fci.frames.from_wire``). libfranka first takes the rotation
    part of each pose by polar decomposition (``Affine3d::rotation()``); for the
    orthonormal blocks a valid pose carries that is the block itself to rounding,
    so the block is used as is. ``cutoff`` is a scalar or one per robot, (n,).
    Like :func:`lowpass_filter` this is the arithmetic only: ControlLoop skips it
    when ``cutoff >= MAX_CUTOFF_FREQUENCY``.

    Raises:
        ValueError: cutoff zero, negative or not finite; ``T_c`` or ``T_ref`` with a
            NaN or infinite entry (libfranka throws std::invalid_argument, in this order).
    """
    cutoff = _check_cutoff(cutoff, _MSG_CARTESIAN_CUTOFF)
    T_c = _finite("T_c", T_c, _MSG_CARTESIAN_SIGNAL)
    T_ref = _finite("T_ref", T_ref, _MSG_CARTESIAN_SIGNAL)
    gain = np.asarray(lowpass_gain(cutoff))
    R_c, R_ref = T_c[..., :3, :3], T_ref[..., :3, :3]
    q_ref = _rotation_to_quaternion(R_ref)
    q = _quaternion_slerp(
        q_ref, q_ref if _same_bits(R_c, R_ref) else _rotation_to_quaternion(R_c), gain
    )
    q /= np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]
    out = np.array(np.broadcast_to(T_c, np.broadcast_shapes(T_c.shape, T_ref.shape)))
    g = gain[..., None]
    out[..., :3, 3] = g * T_c[..., :3, 3] + (1.0 - g) * T_ref[..., :3, 3]
    out[..., :3, :3] = _quaternion_to_rotation(q)
    return out


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two float64 arrays of one shape are equal bit for bit (0.0 and -0.0 differ:
    a conversion's result may keep the sign of a zero). A translation-only command keeps
    the reference's orientation exactly: its quaternion is the reference's."""
    return a.shape == b.shape and count_nonzero(a.view(np.int64) == b.view(np.int64)) == a.size


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
    twist_c = _finite("twist_c", twist_c, _MSG_TWIST)
    twist_last, dtwist_last, limits = _twist_history(
        twist_last, dtwist_last, (v_max, a_max, j_max, v_rot_max, a_rot_max, j_rot_max)
    )
    return _limit_twist(twist_c, twist_last, dtwist_last, *limits)


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
       ``AngleAxisd`` of the difference, axis * angle with the angle in [0, pi],
       computed through the quaternion, so exact up to a half turn);
    2. that twist goes through :func:`limit_rate_cartesian_velocity` against
       ``twist_last`` / ``dtwist_last``, with the rotational limits scaled by
       kFactorCartesianRotationPoseInterface = 0.99 (include/franka/rate_limiting.h)
       here -- pass the robot's plain kMaxRotational* values, as ControlLoop does;
    3. the limited twist ``(v, w)`` is integrated over one cycle: ``t_last + v dt``,
       and, if ``|w| > kNormEps``, ``R = Rot(w / |w|, |w| dt) @ R_last`` (Rodrigues:
       ``I + sin(th) K + (1 - cos(th)) K^2``); otherwise ``R = R_last``.

    The result's bottom row is [0, 0, 0, 1]. Poses are row-major numpy matrices
    (not the wire layout). libfranka takes each rotation block by polar
    decomposition first (``Affine3d::rotation()``); the blocks are used as they
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
    T_c = _finite("T_c", T_c, _MSG_POSE)
    if count_nonzero(is_homogeneous(T_c.reshape(-1, 4, 4))) != T_c.size // 16:
        raise ValueError(f"T_c: {_MSG_POSE_INVALID} (libfranka throws std::invalid_argument)")
    T_last = _finite("T_last", T_last)
    twist_last, dtwist_last, limits = _twist_history(
        twist_last, dtwist_last, (v_max, a_max, j_max, v_rot_max, a_rot_max, j_rot_max)
    )
    v_max, a_max, j_max, v_rot_max, a_rot_max, j_rot_max = limits
    dt = DELTA_T
    t_last = T_last[..., :3, 3]
    R_last = T_last[..., :3, :3]
    R_diff = T_c[..., :3, :3] @ np.swapaxes(R_last, -1, -2)
    twist = np.empty((*R_diff.shape[:-2], 6))
    np.divide(T_c[..., :3, 3] - t_last, dt, out=twist[..., :3])
    np.divide(_rotation_vector(R_diff), dt, out=twist[..., 3:])
    rotational = (_ROTATION_POSE_FACTOR * x for x in (v_rot_max, a_rot_max, j_rot_max))
    twist = _limit_twist(twist, twist_last, dtwist_last, v_max, a_max, j_max, *rotational)
    w = twist[..., 3:]
    w_norm = _norm(w)
    rotating = w_norm > _NORM_EPS
    axis = w / np.where(rotating, w_norm, 1.0)[..., None]
    theta = dt * w_norm
    K = skew(axis)
    step = (
        np.eye(3)
        + np.sin(theta)[..., None, None] * K
        + (1.0 - np.cos(theta))[..., None, None] * (K @ K)
    )
    out = np.zeros(np.broadcast_shapes(T_c.shape, T_last.shape))
    out[..., 3, 3] = 1.0
    out[..., :3, 3] = t_last + twist[..., :3] * dt
    out[..., :3, :3] = np.where(rotating[..., None, None], step @ R_last, R_last)
    return out


def _twist_history(twist_last, dtwist_last, limits) -> tuple:
    """The last commanded twist and its rate, and the six limits, as validated float64
    (both Cartesian limiters take them alike)."""
    return (
        _finite("twist_last", twist_last),
        _finite("dtwist_last", dtwist_last),
        _finite_limits(*limits),
    )


def _finite_limits(*limits: ArrayLike) -> list[np.ndarray]:
    names = ("v_max", "a_max", "j_max", "v_rot_max", "a_rot_max", "j_rot_max")
    if all(type(x) is float and math.isfinite(x) for x in limits):
        # The common call (the env's six constants): no array round trip per limit.
        return [np.float64(x) for x in limits]
    return [_finite(name, value) for name, value in zip(names, limits, strict=True)]


def _limit_twist(dx, dx_last, ddx_last, v, a, j, v_rot, a_rot, j_rot) -> np.ndarray:
    """The 6-vector limiter of src/rate_limiting.cpp, on validated float64 arrays.

    Both halves go through :func:`_limit_norm` at once, as (..., 2, 3) with the
    limits paired as (..., 2).
    """
    shape = np.broadcast_shapes(dx.shape, dx_last.shape, ddx_last.shape)
    halves = (*shape[:-1], 2, 3)
    dx, dx_last, ddx_last = (
        (x if x.shape == shape else np.broadcast_to(x, shape)).reshape(halves)
        for x in (dx, dx_last, ddx_last)
    )
    out = _limit_norm(dx, dx_last, ddx_last, _pair(v, v_rot), _pair(a, a_rot), _pair(j, j_rot))
    return out.reshape(shape)


def _pair(translational: np.ndarray, rotational: np.ndarray) -> np.ndarray:
    """Two limits side by side on a new last axis: (2,) for scalars, else (..., 2)."""
    if translational.ndim == 0 and rotational.ndim == 0:
        return np.array((translational, rotational))
    return np.stack(np.broadcast_arrays(translational, rotational), axis=-1)


def _limit_norm(v_c, v_last, a_last, v_max, a_max, j_max) -> np.ndarray:
    """The private 3-vector limiter of src/rate_limiting.cpp: vectors (..., 3), limits (...)."""
    dt = DELTA_T
    eps = _NORM_EPS
    # Jerk by differentiation; its norm clamped to J (direction kept) and integrated.
    jerk = ((v_c - v_last) / dt - a_last) / dt
    jerk_norm = _norm(jerk)
    jerking = jerk_norm > eps
    jerk_step = np.minimum(jerk_norm, j_max)  # (libfranka also clamps at -J: a norm never is)
    acc = a_last + jerk / np.where(jerking, jerk_norm, 1.0)[..., None] * jerk_step[..., None] * dt
    acc = np.where(jerking[..., None], acc, a_last)
    # Distance from v_last, along the acceleration's direction, to the sphere |v| = V.
    acc_norm = _norm(acc)
    moving = acc_norm > eps
    unit = acc / np.where(moving, acc_norm, 1.0)[..., None]
    dot = np.einsum("...i,...i->...", unit, v_last)
    disc = dot * dot - np.einsum("...i,...i->...", v_last, v_last) + v_max * v_max
    distance = np.sqrt(np.maximum(disc, 0.0)) - dot
    safe = np.minimum(j_max / a_max * distance, a_max)
    # disc < 0 (v_last outside the ball): libfranka's sqrt gives NaN and
    # std::min(|a|, NaN) returns |a| -- the acceleration norm goes through unlimited.
    size = np.where(disc < 0.0, acc_norm, np.minimum(acc_norm, safe))
    return np.where(moving[..., None], v_last + unit * size[..., None] * dt, v_last)


def _norm(x: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis."""
    return np.sqrt(np.einsum("...i,...i->...", x, x))


def _rotation_to_quaternion(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 4) quaternions (w, x, y, z), Shepperd's method.

    Eigen's conversion (``Quaternion(const Matrix3&)``): if the trace is positive,
    ``w`` is computed first (then ``w > 0``); otherwise the component of the
    largest diagonal entry (first one on ties), so the square root is always
    taken of a number >= 1 and nothing is divided by a small value. Row ``b`` of
    the symmetric matrix ``K`` (:data:`_SHEPPERD_ROWS`) is ``4 q_b q``; the chosen
    row divided by ``4 q_b = 2 sqrt(K[b, b])`` is the quaternion.
    """
    lead = R.shape[:-2]
    flat = R.reshape(-1, 9)
    m00, m11, m22 = flat[:, 0], flat[:, 4], flat[:, 8]
    trace = m00 + m11 + m22
    positive = trace > 0.0
    n_positive = count_nonzero(positive)
    if n_positive == len(flat):
        # Every angle below 120 degrees -- always so for the pose limiter's one-cycle
        # difference: row 0 for all.
        return _quaternion_from_row(flat, 0, trace).reshape(*lead, 4)
    # The largest diagonal entry, the first one on ties (argmax's rule too).
    largest = np.argmax(flat[:, ::4], axis=1) + 1
    branch = largest if n_positive == 0 else np.where(positive, 0, largest)
    first = int(branch[0])
    if count_nonzero(branch == first) == len(flat):
        # One branch for every rotation (always so for one arm; a half turn about x,
        # the FR3's flange pointing down, takes row 1).
        return _quaternion_from_row(flat, first, trace).reshape(*lead, 4)
    q = np.empty((len(flat), 4))
    for b in np.unique(branch).tolist():
        rows = branch == b
        q[rows] = _quaternion_from_row(flat[rows], b, trace[rows])
    return q.reshape(*lead, 4)


def _quaternion_from_row(flat: np.ndarray, b: int, trace: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions from row ``b`` of Shepperd's ``K`` of (n, 9) row-major rotations.

    The diagonal entry ``K[b, b] = 4 q_b^2`` is ``trace + 1`` (b = 0) or, for b = 1, 2, 3,
    ``1 + 2 m_bb - trace`` evaluated as ``m_bb - m_b'b' - m_b''b'' + 1``; the other three
    entries of the row are skew differences or symmetric sums of R (:data:`_SHEPPERD_ROWS`).
    """
    if b == 0:
        k_bb = trace + 1.0
    else:
        d0, d1, d2 = (flat[:, 4 * ((b - 1 + k) % 3)] for k in range(3))
        k_bb = d0 - d1 - d2 + 1.0
    others, plus, minus, sign = _SHEPPERD_ROWS[b]
    t = np.sqrt(k_bb)
    q = np.empty((len(flat), 4))
    q[:, b] = 0.5 * t
    q[:, others] = (flat[:, plus] + sign * flat[:, minus]) * (0.5 / t)[:, None]
    return q


#: Row b of Shepperd's symmetric K, off the diagonal: the quaternion components it
#: yields, and each entry as flat[plus] + sign * flat[minus] over the row-major R --
#: K[0, 1:] = (R21 - R12, R02 - R20, R10 - R01), K[1, 2] = R01 + R10,
#: K[1, 3] = R02 + R20, K[2, 3] = R12 + R21.
_SHEPPERD_ROWS = tuple(
    (np.array(others), np.array(plus), np.array(minus), np.array(sign))
    for others, plus, minus, sign in (
        ((1, 2, 3), (7, 2, 3), (5, 6, 1), (-1.0, -1.0, -1.0)),
        ((0, 2, 3), (7, 1, 2), (5, 3, 6), (-1.0, 1.0, 1.0)),
        ((0, 1, 3), (2, 1, 5), (6, 3, 7), (-1.0, 1.0, 1.0)),
        ((0, 1, 2), (3, 2, 5), (1, 6, 7), (-1.0, 1.0, 1.0)),
    )
)


def _quaternion_to_rotation(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) to (..., 3, 3) rotation matrices.

    Entry by entry ``R[i, j] = [1 -] (P[a] +- P[b])`` over the products ``P[k, l] =
    (2 q_k) q_l`` (:data:`_QUATERNION_TERMS`): e.g. ``R[0, 0] = 1 - (2yy + 2zz)``,
    ``R[0, 1] = 2xy - 2zw``, as Eigen's ``toRotationMatrix`` -- in a few array calls.
    """
    lead = q.shape[:-1]
    P = ((2.0 * q)[..., :, None] * q[..., None, :]).reshape(*lead, 16)
    R = P[..., _QUATERNION_TERMS[0]] + _QUATERNION_TERMS[2] * P[..., _QUATERNION_TERMS[1]]
    R[..., ::4] = 1.0 - R[..., ::4]
    return R.reshape(*lead, 3, 3)


#: _quaternion_to_rotation: for each entry of R (row-major), the flat indices a and b
#: into the products P (index 4k + l for (2 q_k) q_l, q = (w, x, y, z)) and the sign
#: of P[b]; the diagonal entries are then taken from 1.
_QUATERNION_TERMS = (
    np.array([10, 6, 7, 6, 5, 11, 7, 11, 5]),  # yy, xy, xz; xy, xx, yz; xz, yz, xx
    np.array([15, 12, 8, 12, 15, 4, 8, 4, 10]),  # zz, zw, yw; zw, zz, xw; yw, xw, yy
    np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0]),
)


def _quaternion_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Eigen's ``q0.slerp(t, q1)``, (..., 4): shorter arc, linear once |q0 . q1| >= 1 - eps."""
    d = np.einsum("...i,...i->...", q0, q1)
    abs_d = np.abs(d)
    linear = abs_d >= _SLERP_LINEAR
    if count_nonzero(linear) == linear.size:
        # Every pair (nearly) equal -- a settled orientation: no trigonometry.
        s0, s1 = np.broadcast_to(1.0 - t, d.shape), np.broadcast_to(t, d.shape)
    else:
        theta = np.arccos(np.minimum(abs_d, 1.0))
        sin_theta = np.where(linear, 1.0, np.sin(theta))
        s0 = np.where(linear, 1.0 - t, np.sin((1.0 - t) * theta) / sin_theta)
        s1 = np.where(linear, t, np.sin(t * theta) / sin_theta)
    s1 = np.where(d < 0.0, -s1, s1)
    return s0[..., None] * q0 + s1[..., None] * q1


def _rotation_vector(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations to (..., 3) axis * angle, angle in [0, pi]: Eigen's AngleAxisd.

    Through the quaternion: angle ``2 atan2(|v|, |w|)``, axis ``v / |v|`` with the
    sign of ``w`` (so the angle stays <= pi); the zero rotation gives zero. Exact
    near a half turn, where the matrix's skew part vanishes.
    """
    q = _rotation_to_quaternion(R)
    w, vec = q[..., 0], q[..., 1:]
    n = _norm(vec)
    turning = n > 0.0
    angle = 2.0 * np.arctan2(n, np.abs(w))
    axis = vec / np.where(w < 0.0, -n, np.where(turning, n, 1.0))[..., None]
    return np.where(turning[..., None], axis * angle[..., None], 0.0)


def interpolate_core(q_from: np.ndarray, q_to: np.ndarray, s: float) -> np.ndarray:
    """:func:`interpolate`'s linear arithmetic, unchecked: for inputs validated once (the
    env's client calls it every cycle of a step whose ends :func:`interpolate` checked).
    The same expression, so the same bits."""
    return (1.0 - s) * q_from + s * q_to


def interpolate(
    q_from: ArrayLike, q_to: ArrayLike, alpha: ArrayLike, kind: str = "linear"
) -> np.ndarray:
    """``q_from + s(alpha) * (q_to - q_from)``: one cycle of the env's "interpolate" filter.

    Not a libfranka function. ``s(alpha) = alpha`` (``kind="linear"``) or
    ``0.5 * (1 - cos(pi * alpha))`` (``kind="cosine"``, zero slope at both ends).
    ``alpha`` in [0, 1] is a scalar or broadcasts against ``q_from`` (use shape
    (n, 1) for one phase per robot); 0 gives ``q_from``, 1 gives ``q_to`` exactly.

    Raises:
        ValueError: unknown ``kind``; ``alpha`` outside [0, 1] or not finite;
            non-finite ``q_from`` / ``q_to``.
    """
    if kind not in _INTERPOLATION_KINDS:
        raise ValueError(
            f"unknown interpolation kind {kind!r}: expected one of {_INTERPOLATION_KINDS}"
        )
    a = np.asarray(alpha, dtype=np.float64)
    if not (np.isfinite(a).all() and (a >= 0.0).all() and (a <= 1.0).all()):
        raise ValueError(f"interpolation alpha must be finite and in [0, 1], got {alpha!r}")
    q_from = _finite("q_from", q_from)
    q_to = _finite("q_to", q_to)
    s = a if kind == "linear" else 0.5 * (1.0 - np.cos(np.pi * a))
    # Written so that s == 1 returns q_to bit-exactly (q_from + (q_to - q_from) may not).
    return (1.0 - s) * q_from + s * q_to
