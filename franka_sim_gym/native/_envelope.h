/* libfranka's position-based joint velocity envelope (src/joint_velocity_limits.cpp),
 * one entry at a time: fci/tables.py RobotTable.velocity_envelope_halves, the rule, in
 * C for the env's libfranka client, which limits against it (envs/_client_filters.c).
 * Its constants come from the robot's table (RobotTable.envelope_table). */
#ifndef FRANKA_SIM_GYM_ENVELOPE_H
#define FRANKA_SIM_GYM_ENVELOPE_H

#include <math.h>

#include "_arrays.h"

/* The envelope's constants, (4, 14): rows 2 a_dec, bound ([q_upper | -q_lower]),
 * v_off and v_max, each doubled as [upper half | lower half]
 * (RobotTable.envelope_table). */
static const Py_ssize_t CONSTANTS_SHAPE[2] = {4, 14};

/* Half k (0-13) of the envelope at joint value q: velocity_envelope_halves, one entry.
 * The lower half is the same law on the mirrored range (q * -1). */
static inline double envelope_entry(const F64 *c, int k, double q, double shift)
{
    double r = k < 7 ? q : -q;
    r = AT2(*c, 1, k) - r; /* distance to the stop */
    r *= AT2(*c, 0, k);
    r = np_maximum(r, 0.0);
    r = sqrt(r);
    double offset = AT2(*c, 2, k);
    r = np_maximum(r, offset); /* max(0, s - v_off) as max(s, v_off) - v_off */
    r -= offset;
    r = np_minimum(r, AT2(*c, 3, k));
    return r - shift;
}

#endif
