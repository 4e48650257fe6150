/* The rotation library's one text (sim/rotations.py calls it through sim/_rotations.c;
 * envs/_client_filters.c's pose rules and fci/cartesian/_history.c call it directly): one
 * rotation at a time, row-major arrays of nine doubles, quaternions (w, x, y, z) as Eigen
 * stores them. Each matrix product sums over k = 0, 1, 2 in that order, without fused
 * multiply-adds (setup.py); 3- and 4-vector dot products sum in the order numpy's einsum
 * takes on x86-64 (its two-lane float64 loops). No rule of the robot lives here.
 *
 * The thresholds are sim/rotations.py's (NEAR_PI, TURNING_ABOVE, SERIES_BELOW,
 * SLERP_LINEAR), handed to each including module (its configure(), or a plan's constants)
 * and kept in its ROTATION. */
#ifndef FRANKA_SIM_GYM_NATIVE_ROTATION_H
#define FRANKA_SIM_GYM_NATIVE_ROTATION_H

#include <math.h>

#include "_arrays.h" /* np_minimum */

#ifndef M_PI /* (strict C99's math.h leaves it out) */
#define M_PI 3.14159265358979323846
#endif

/* sim/rotations.py's thresholds, as the including module's configure() received them. */
static struct {
    double near_pi, turning_above, series_below, slerp_linear;
} ROTATION;

/* ROTATION from (near_pi, turning_above, series_below, slerp_linear), as configure()
 * received them. */
static inline void rotation_configure(const double *v)
{
    ROTATION.near_pi = v[0];
    ROTATION.turning_above = v[1];
    ROTATION.series_below = v[2];
    ROTATION.slerp_linear = v[3];
}

/* x . y over three values, summed in numpy einsum's order for "...i,...i->...". */
static inline double dot3(const double *x, const double *y)
{
    return (x[0] * y[0] + x[2] * y[2]) + x[1] * y[1];
}

/* out = a @ b, or a @ b^T with transpose_b. */
static inline void mat3_mul(const double *a, const double *b, int transpose_b, double *out)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++)
                s += a[3 * r + k] * (transpose_b ? b[3 * c + k] : b[3 * k + c]);
            out[3 * r + c] = s;
        }
}

/* E = (I + a K) + b K^2 with K = skew(v): Rodrigues' formula, its coefficients given. */
static inline void rodrigues(const double v[3], double a, double b, double *E)
{
    const double K[9] = {0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0};
    double KK[9];
    mat3_mul(K, K, 0, KK);
    for (int k = 0; k < 9; k++) E[k] = ((k % 4 == 0 ? 1.0 : 0.0) + a * K[k]) + b * KK[k];
}

/* rotation_to_quaternion: Shepperd's method as Eigen's Quaternion(const Matrix3&),
 * (w, x, y, z), row-major m. */
static inline void rotation_to_quaternion(const double *m, double *q)
{
    double trace = (m[0] + m[4]) + m[8];
    int b = 0;
    if (!(trace > 0.0)) { /* the largest diagonal entry, the first on ties */
        b = 1;
        if (m[4] > m[0]) b = 2;
        if (m[8] > m[4 * (b - 1)]) b = 3;
    }
    double k_bb;
    if (b == 0) {
        k_bb = trace + 1.0;
    } else {
        double d0 = m[4 * (b - 1)], d1 = m[4 * (b % 3)], d2 = m[4 * ((b + 1) % 3)];
        k_bb = d0 - d1 - d2 + 1.0;
    }
    double t = sqrt(k_bb), inv = 0.5 / t;
    q[b] = 0.5 * t;
    switch (b) {
    case 0:
        q[1] = (m[7] - m[5]) * inv;
        q[2] = (m[2] - m[6]) * inv;
        q[3] = (m[3] - m[1]) * inv;
        break;
    case 1:
        q[0] = (m[7] - m[5]) * inv;
        q[2] = (m[1] + m[3]) * inv;
        q[3] = (m[2] + m[6]) * inv;
        break;
    case 2:
        q[0] = (m[2] - m[6]) * inv;
        q[1] = (m[1] + m[3]) * inv;
        q[3] = (m[5] + m[7]) * inv;
        break;
    default:
        q[0] = (m[3] - m[1]) * inv;
        q[1] = (m[2] + m[6]) * inv;
        q[2] = (m[5] + m[7]) * inv;
    }
}

/* quaternion_to_rotation: R[i, j] = [1 -] (P[a] +- P[b]) over P[k, l] = (2 q_k) q_l. */
static inline void quaternion_to_rotation(const double *q, double *R)
{
    double P[16];
    for (int k = 0; k < 4; k++)
        for (int l = 0; l < 4; l++) P[4 * k + l] = (2.0 * q[k]) * q[l];
    static const int A[9] = {10, 6, 7, 6, 5, 11, 7, 11, 5};
    static const int B[9] = {15, 12, 8, 12, 15, 4, 8, 4, 10};
    static const double SIGN[9] = {1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0};
    for (int e = 0; e < 9; e++) {
        double v = P[A[e]] + SIGN[e] * P[B[e]];
        R[e] = e % 4 == 0 ? 1.0 - v : v;
    }
}

/* x . y over four values, in numpy einsum's order for "...i,...i->...". */
static inline double dot4(const double *x, const double *y)
{
    return (x[0] * y[0] + x[2] * y[2]) + (x[1] * y[1] + x[3] * y[3]);
}

/* quaternion_slerp: Eigen's q0.slerp(t, q1); linear once |q0 . q1| >= 1 - eps. */
static inline void quaternion_slerp(const double *q0, const double *q1, double t, double *out)
{
    double d = dot4(q0, q1), abs_d = fabs(d), s0, s1;
    if (abs_d >= ROTATION.slerp_linear) {
        s0 = 1.0 - t;
        s1 = t;
    } else {
        double theta = acos(np_minimum(abs_d, 1.0)), sin_theta = sin(theta);
        s0 = sin((1.0 - t) * theta) / sin_theta;
        s1 = sin(t * theta) / sin_theta;
    }
    if (d < 0.0) s1 = -s1;
    for (int k = 0; k < 4; k++) out[k] = s0 * q0[k] + s1 * q1[k];
}

/* rotation_log: axis * angle, angle = atan2(|vee|, trace - 1) of the skew part vee; the
 * axis from the quaternion within near_pi of a half turn. */
static inline void rotation_log(const double *m, double *out)
{
    double vee[3] = {m[7] - m[5], m[2] - m[6], m[3] - m[1]};
    double two_sin = sqrt(dot3(vee, vee));
    double angle = atan2(two_sin, ((m[0] + m[4]) + m[8]) - 1.0);
    double scale = two_sin > ROTATION.turning_above ? angle / two_sin : 0.5;
    for (int k = 0; k < 3; k++) out[k] = vee[k] * scale;
    if (!(M_PI - angle < ROTATION.near_pi)) return;
    double q[4];
    rotation_to_quaternion(m, q);
    double n = sqrt(dot3(q + 1, q + 1));
    if (!(n > 0.0)) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    double half = 2.0 * atan2(n, fabs(q[0]));
    double div = q[0] < 0.0 ? -n : n;
    for (int k = 0; k < 3; k++) out[k] = q[k + 1] / div * half;
}

/* relative_rotation_log: rotation_log(A^T B), the rotation vector taking A to B in A's
 * (the body) frame. */
static inline void relative_rotation_log(const double *A, const double *B, double *out)
{
    double At[9], M[9];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) At[3 * r + c] = A[3 * c + r];
    mat3_mul(At, B, 0, M);
    rotation_log(M, out);
}

/* rotation_exp: the rotation of the rotation vector rv (axis * angle), Rodrigues with
 * sin t / t and (1 - cos t) / t^2, their series below series_below. */
static inline void rotation_exp(const double rv[3], double *E)
{
    double angle = sqrt((rv[0] * rv[0] + rv[1] * rv[1]) + rv[2] * rv[2]);
    double a2 = angle * angle;
    if (angle < ROTATION.series_below)
        rodrigues(rv, 1.0 - a2 / 6.0, 0.5 - a2 / 24.0, E);
    else
        rodrigues(rv, sin(angle) / angle, (1.0 - cos(angle)) / a2, E);
}

/* out = rotation_exp(rv) @ R. */
static inline void exp_left(const double rv[3], const double *R, double *out)
{
    double E[9];
    rotation_exp(rv, E);
    mat3_mul(E, R, 0, out);
}

/* out = R^T R of a row-major 3x3 matrix. */
static inline void gram3(const double *R, double *out)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += R[3 * k + r] * R[3 * k + c];
            out[3 * r + c] = s;
        }
}

/* nearest_rotation, in place: three Newton-Schulz steps R <- (R (3 I - R^T R)) / 2. */
static inline void nearest_rotation(double *R)
{
    double G[9], next[9];
    for (int it = 0; it < 3; it++) {
        gram3(R, G);
        for (int k = 0; k < 9; k++) G[k] = (k % 4 == 0 ? 3.0 : 0.0) - G[k];
        mat3_mul(R, G, 0, next);
        for (int k = 0; k < 9; k++) R[k] = 0.5 * next[k];
    }
}

#endif
