/* The FR3's (and the FER's) position-based joint velocity envelope, libfranka >= 0.18
 * src/joint_velocity_limits.cpp (docs/limits.md section 4; fci/tables.py
 * RobotTable.velocity_envelope): the law's one text, read by the robot's rules
 * (fci/limits/_joint.c) and by the env's client, whose rate limiter runs inside the band
 * at its last commanded position (envs/_client_filters.c joint_cycle).
 *
 * ``constants`` (7, 7) rows: RobotTable.joint_constants' q_lower, q_upper, ddq_max,
 * dddq_max, 2 ddq_decel, dq_offset, dq_max; ``positional`` 0 for a robot whose envelope is
 * the constant dq_max (the FER). Arithmetic in the order numpy's text had it, numpy's
 * NaN-propagating minimum and maximum. */
#ifndef FRANKA_SIM_GYM_NATIVE_ENVELOPE_H
#define FRANKA_SIM_GYM_NATIVE_ENVELOPE_H

#include <math.h>

#include "_arrays.h"

enum { Q_LOWER, Q_UPPER, DDQ_MAX, DDDQ_MAX, TWO_A, OFFSET, VMAX, N_CONSTANTS };

/* numpy's np.maximum / np.minimum of two doubles: a NaN in either is the result. */
static inline double nan_max(double a, double b)
{
    return (a >= b || isnan(a)) ? a : b;
}
static inline double nan_min(double a, double b)
{
    return (a <= b || isnan(a)) ? a : b;
}

/* One half of the envelope in RobotTable.velocity_envelope_halves' order: ``distance``
 * to the stop (q_upper - q, or -q_lower - (-q) for the mirrored lower half). */
static inline double envelope_half(const F64 *c, int j, double distance, int positional,
                                   double shift)
{
    if (!positional) return AT2(*c, VMAX, j) - shift;
    double r = distance * AT2(*c, TWO_A, j);
    r = sqrt(nan_max(r, 0.0));
    r = nan_max(r, AT2(*c, OFFSET, j));
    r -= AT2(*c, OFFSET, j);
    r = nan_min(r, AT2(*c, VMAX, j));
    return r - shift;
}

/* (upper, lower) of the envelope at q for joint j. */
static ALWAYS_INLINE void envelope(const F64 *c, int j, double q, int positional, double shift,
                            double *upper, double *lower)
{
    *upper = envelope_half(c, j, AT2(*c, Q_UPPER, j) - q * 1.0, positional, shift);
    *lower = -envelope_half(c, j, (-AT2(*c, Q_LOWER, j)) - q * -1.0, positional, shift);
}

#endif
