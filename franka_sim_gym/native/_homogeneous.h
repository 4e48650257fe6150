/* libfranka's isHomogeneousTransformation (docs/libfranka-client.md §9), the robot's check
 * of every pose command and the client's before it sends one: its only text, included by
 * fci/_frames.c (fci/frames.py's verdicts) and fci/_arrival.c (a pose command on arrival).
 *
 * A pose passes when all 16 entries are finite, its bottom row is exactly [0, 0, 0, 1] and
 * every row and every column of its rotation block has a norm within tol of 1 (no
 * determinant check, as libfranka). */
#ifndef FRANKA_SIM_GYM_NATIVE_HOMOGENEOUS_H
#define FRANKA_SIM_GYM_NATIVE_HOMOGENEOUS_H

#include <math.h>

/* |sqrt(norm2) - 1| <= tol. */
static inline int unit_norm(double norm2, double tol) { return fabs(sqrt(norm2) - 1.0) <= tol; }

/* Whether the row-major 4 x 4 ``m`` passes. */
static inline int homogeneous_passes(const double m[16], double tol)
{
    for (int k = 0; k < 16; k++)
        if (!isfinite(m[k])) return 0;
    if (!(m[12] == 0.0 && m[13] == 0.0 && m[14] == 0.0 && m[15] == 1.0)) return 0;
    /* The squares summed as numpy's einsum summed them: a row's as (x0 + x2) + x1, a
     * column's in order (the verdicts of the numpy text this replaced, to the last bit). */
    for (int k = 0; k < 3; k++) {
        const double *row = m + 4 * k;
        double r2 = (row[0] * row[0] + row[2] * row[2]) + row[1] * row[1];
        double c2 = (m[k] * m[k] + m[4 + k] * m[4 + k]) + m[8 + k] * m[8 + k];
        if (!unit_norm(r2, tol) || !unit_norm(c2, tol)) return 0;
    }
    return 1;
}

#endif
