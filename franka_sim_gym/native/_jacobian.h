/* The geometric Jacobian at a point of the arm's last link, one robot's rows: the one text
 * of sim/dynamics.py jacobian_at (sim/_dynamics.c) and of the contact sensing's Jacobian
 * at K (fci/contact/_contact.c Sensing). Column j is [z_j x (p - o_j); z_j] with z_j the
 * joint's unit axis and o_j a point of it.
 *
 * Each component of the cross product is one product minus another plus zeros, added
 * from a zero (the sum the deleted Levi-Civita contraction made, so trajectories kept
 * their bits, the sign of a zero included). Built without fused multiply-adds (setup.py);
 * tests/sim/test_dynamics.py holds it to MuJoCo's own mj_jac. */
#ifndef FRANKA_SIM_GYM_NATIVE_JACOBIAN_H
#define FRANKA_SIM_GYM_NATIVE_JACOBIAN_H

#include "_arrays.h"

/* Robot i's (6, 7) Jacobian of point[i] into out[i]: axes / anchors (n, 7, 3), point (n, 3),
 * out (n, 6, 7). */
static inline void jacobian_row(const F64 *axes, const F64 *anchors, const F64 *point,
                                Py_ssize_t i, F64 *out)
{
    for (int j = 0; j < 7; j++) {
        double z[3], l[3];
        for (int k = 0; k < 3; k++) {
            z[k] = AT3(*axes, i, j, k);
            l[k] = AT2(*point, i, k) - AT3(*anchors, i, j, k);
        }
        /* eps_iab z_a l_b summed from zero: z_a l_b - z_b l_a, never a negative zero */
        AT3(*out, i, 0, j) = 0.0 + (z[1] * l[2] - z[2] * l[1]);
        AT3(*out, i, 1, j) = 0.0 + (z[2] * l[0] - z[0] * l[2]);
        AT3(*out, i, 2, j) = 0.0 + (z[0] * l[1] - z[1] * l[0]);
        for (int k = 0; k < 3; k++) AT3(*out, i, 3 + k, j) = z[k];
    }
}

#endif
