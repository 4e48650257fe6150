"""libfranka's client-side joint and torque command filters, batch-first: the env plays
the client.

Pure functions over float64 arrays with a leading robot axis, ``(n, 7)``; any
shapes that broadcast work the same. Each reproduces one piece of libfranka
0.21 operation for operation (docs/limits.md §6), so that a command
stream built here equals the one a ``franka::Robot::control(...)`` loop sends:

* :func:`lowpass_filter` -- ``franka::lowpassFilter`` (include/franka/lowpass_filter.h,
  src/lowpass_filter.cpp), with the gain of :func:`lowpass_gain`;
* :func:`limit_rate_joint_velocities` / :func:`limit_rate_joint_positions` -- the
  scalar velocity and position overloads of ``franka::limitRate``
  (src/rate_limiting.cpp), vectorised over robots and joints;
* :func:`limit_rate_torques` -- the ``limitRate(max_derivatives, commanded,
  last_commanded)`` overload used for torques;
* the Cartesian ones -- ``cartesianLowpassFilter`` and the twist and pose overloads of
  ``limitRate`` -- are :mod:`franka_sim_gym.envs.cartesian_filters`.

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

    # CartesianPose (cartesian_filters; row-major (n, 4, 4), the wire is column-major):
    # reference = the command on the first cycle, state.O_T_EE_c afterwards.
    ref = T_c if first_cycle else state.O_T_EE_c
    T_c = cartesian_lowpass_filter(T_c, ref, cutoff)
    T_c = limit_rate_cartesian_pose(T_c, ref, state.O_dP_EE_c, state.O_ddP_EE_c,
                                    table.v_trans_max, table.a_trans_max, table.j_trans_max,
                                    table.v_rot_max, table.a_rot_max, table.j_rot_max)

    # CartesianVelocities (cartesian_filters): lowpass_filter against state.O_dP_EE_c.
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
with libfranka's message, prefixed by the offending argument. Each rule's arithmetic
has one text, in C (``envs/_client_filters.c``, :mod:`franka_sim_gym.envs.client_kernel`):
these functions check and broadcast their arguments and call it; the env's client, which
validates its inputs once, calls it directly every cycle.

:func:`interpolate` is not libfranka: it is the plain per-cycle interpolation
of the env's ``"interpolate"`` action filter.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..fci.tables import DELTA_T
from .client_kernel import RULES

__all__ = [
    "DELTA_T",
    "LOWPASS_DEFAULT_CUTOFF",
    "MAX_CUTOFF_FREQUENCY",
    "check_cutoff",
    "finite",
    "interpolate",
    "interpolate_core",
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
#: The joint limiters' arguments after the command (and q_last), as errors name them.
_LIMITER_ARGS = ("dq_last", "ddq_last", "upper", "lower", "ddq_max", "dddq_max")


def finite(name: str, value: ArrayLike, message: str | None = None) -> np.ndarray:
    """``value`` as float64; ValueError naming ``name`` if any entry is NaN or infinite.

    ``message`` is libfranka's own where libfranka checks this very value (and
    throws std::invalid_argument); references and limits, which libfranka does
    not check up front (a NaN there only surfaces in the final checkFinite of the
    command), get a plain message.
    """
    array = np.asarray(value, dtype=np.float64)
    if not np.isfinite(array).all():
        if message is None:
            raise ValueError(f"{name} contains NaN or infinite entries")
        raise ValueError(f"{name}: {message} (libfranka throws std::invalid_argument)")
    return array


def check_cutoff(cutoff: ArrayLike, message: str = _MSG_CUTOFF) -> np.ndarray:
    """``cutoff`` as float64; ValueError with libfranka's ``message`` unless every entry
    is a positive finite number."""
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
    c = check_cutoff(cutoff)
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
    x = finite("x", x, _MSG_SIGNAL)
    x_ref = finite("x_ref", x_ref, _MSG_SIGNAL)
    return _elementwise(RULES.lowpass, x, x_ref, np.asarray(gain, dtype=np.float64))


def _elementwise(rule, *arrays: np.ndarray) -> np.ndarray:
    """``rule`` (envs/_client_filters.c) on ``arrays`` broadcast together, element by
    element: these rules treat every joint value on its own (their limits are per value
    once broadcast), so the broadcast values are laid out as rows of seven, the C rules'
    shape (the last row padded with copies of the last value), and the result is given
    back in the broadcast shape (a scalar for scalars)."""
    arrays = np.broadcast_arrays(*arrays)
    shape = arrays[0].shape
    size = arrays[0].size
    if size == 0:
        return np.empty(shape)
    pad = -size % 7
    rows = [np.pad(a.reshape(-1), (0, pad), mode="edge").reshape(-1, 7) for a in arrays]
    out = np.empty((size + pad) // 7 * 7)
    rule(*rows, out.reshape(-1, 7))
    result = out[:size].reshape(shape)
    return result[()] if result.ndim == 0 else result


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
    of src/rate_limiting.cpp (libfranka >= 0.11; docs/limits.md §6.3), per joint,
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
    dq_c = finite("dq_c", dq_c, _MSG_COMMAND)
    limiter = _finite_limiter_args(dq_last, ddq_last, upper, lower, ddq_max, dddq_max)
    return _elementwise(RULES.limit_velocities, dq_c, *limiter)


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
    q_c = finite("q_c", q_c, _MSG_COMMAND)
    q_last = finite("q_last", q_last)
    limiter = _finite_limiter_args(dq_last, ddq_last, upper, lower, ddq_max, dddq_max)
    return _elementwise(RULES.limit_positions, q_c, q_last, *limiter)


def limit_rate_torques(tau_c: ArrayLike, tau_last: ArrayLike, dtau_max: ArrayLike) -> np.ndarray:
    """Rate-limit commanded torques, (n, 7) -> (n, 7).

    ``franka::limitRate(kMaxTorqueRate, tau_c, state.tau_J_d)`` (the
    ``max_derivatives`` overload of src/rate_limiting.cpp)::

        out = tau_last + clamp((tau_c - tau_last) / dt, -dtau_max, dtau_max) * dt

    Raises:
        ValueError: any NaN or infinite entry in the inputs.
    """
    tau_c = finite("tau_c", tau_c, _MSG_COMMAND)
    tau_last = finite("tau_last", tau_last)
    d_max = finite("dtau_max", dtau_max)
    return _elementwise(RULES.limit_torques, tau_c, tau_last, d_max)


def _finite_limiter_args(*values: ArrayLike) -> list[np.ndarray]:
    """The velocity limiter's last velocity and acceleration, bounds and limits, as the
    joint overloads of limitRate take them, each through :func:`finite` in that order."""
    return [finite(name, value) for name, value in zip(_LIMITER_ARGS, values, strict=True)]


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
    q_from = finite("q_from", q_from)
    q_to = finite("q_to", q_to)
    s = a if kind == "linear" else 0.5 * (1.0 - np.cos(np.pi * a))
    # Written so that s == 1 returns q_to bit-exactly (q_from + (q_to - q_from) may not).
    return (1.0 - s) * q_from + s * q_to
