/* 3x3 rotation arithmetic of the C texts (envs/_client_filters.c, the client's pose
 * limiter). Row-major arrays of
 * nine doubles; each product sums over k = 0, 1, 2 in that order. No rule of the robot
 * lives here. */
#ifndef FRANKA_SIM_GYM_NATIVE_ROTATION_H
#define FRANKA_SIM_GYM_NATIVE_ROTATION_H

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

/* out = ((I + a K) + b K^2) @ R with K = skew(v): Rodrigues' rotation composed on the
 * left, its coefficients left to the caller (v a unit axis with a = sin t,
 * b = 1 - cos t; or v the rotation vector itself with a = sin t / t, b = (1 - cos t) / t^2,
 * as sim/rotations.py rotation_exp). */
static inline void rotate_left(const double v[3], double a, double b, const double *R,
                               double *out)
{
    const double K[9] = {0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0};
    double KK[9], E[9];
    mat3_mul(K, K, 0, KK);
    for (int k = 0; k < 9; k++) E[k] = ((k % 4 == 0 ? 1.0 : 0.0) + a * K[k]) + b * KK[k];
    mat3_mul(E, R, 0, out);
}

#endif
