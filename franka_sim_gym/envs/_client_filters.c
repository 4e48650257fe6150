/* The env's libfranka client filters (envs/commands.py _filtered), each a fused copy
 * of its numpy reference:
 *
 *   limit_rate(positions, target, ref, first, gain, q_d, dq_d, ddq_d, constants, shift,
 *              a_max, j_max, out)
 *       joint positions and velocities: libfranka's low-pass filter, then its rate
 *       limiter against the envelope at q_d (client_filters.limit_*_core).
 *   limit_twist(target, ref, dref, gain, limits, out) -> bool
 *       envs/commands.py CommandGenerator._filtered for "cartesian_velocity" with
 *       libfranka's rate limiter: the low-pass filter toward the state's O_dP_EE_c,
 *       then client_filters.limit_rate_cartesian_velocity (the 3-vector norm limiter
 *       of src/rate_limiting.cpp on each half of the twist).
 *   limit_torques(target, ref, gain, dtau_max, out) -> bool
 *       envs/commands.py CommandGenerator._filtered for "torque" with libfranka's rate
 *       limiter: the low-pass filter toward the state's tau_J_d, then
 *       client_filters.limit_torques_core.
 *   limit_pose(target, ref, dref, ddref, gain, limits, rate_limit, out) -> bool
 *       envs/commands.py CommandGenerator._pose_command for "lowpass" and "limit_rate":
 *       the state's O_T_EE_c orthonormalised (_reference_pose), libfranka's Cartesian
 *       low-pass filter toward it (client_filters.cartesian_lowpass_filter) and, with
 *       rate_limit, its pose rate limiter (client_filters.limit_rate_cartesian_pose).
 *
 * Elementwise arithmetic in the reference's order, built without fused multiply-adds
 * (setup.py); the twist limiter's 3-vector dot products sum as numpy's einsum sums
 * three products, (x0 y0 + x2 y2) + x1 y1, so the result is the reference's bits
 * (tests/envs/test_native_client.py, tests/fci/test_native_joint.py).
 *
 * limit_pose is the exception: its reference takes libm's acos, atan2, sin and cos (as
 * libfranka's Eigen does), which numpy's SIMD versions may round differently by an ulp,
 * a polar decomposition by Newton-Schulz iteration where the reference takes numpy's
 * SVD, and 3x3 products that numpy hands to BLAS. It agrees with the reference to
 * rounding (~1e-15), not bit for bit, and declines (False) wherever the reference would
 * raise or a screen is too near its edge to tell (tests/envs/test_native_client.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_envelope.h"
#include "_rotation.h"

#define DELTA_T KERNEL_DT

/* client_filters._NORM_EPS: libfranka's kNormEps, float64 machine epsilon. */
static const double NORM_EPS = 2.220446049250313e-16;

/* x . y over three values, summed in numpy einsum's order for "...i,...i->...". */
static inline double dot3(const double *x, const double *y)
{
    return (x[0] * y[0] + x[2] * y[2]) + x[1] * y[1];
}

/* Whether every entry of an (n, cols) array (float64 or float32) is finite. */
static int all_finite(const F64 *a, Py_ssize_t n, int cols)
{
    for (Py_ssize_t i = 0; i < n; i++)
        for (int k = 0; k < cols; k++)
            if (!isfinite(num2(a, i, k))) return 0;
    return 1;
}

/* client_filters._limit_norm on one 3-vector: v_c the command, v_last / a_last the last
 * commanded velocity and acceleration, (v_max, a_max, j_max) the limits. */
static void limit_norm(const double *v_c, const double *v_last, const double *a_last,
                       double v_max, double a_max, double j_max, double *out)
{
    const double dt = DELTA_T;
    double jerk[3], acc[3], unit[3];
    for (int k = 0; k < 3; k++) jerk[k] = ((v_c[k] - v_last[k]) / dt - a_last[k]) / dt;
    double jerk_norm = sqrt(dot3(jerk, jerk));
    int jerking = jerk_norm > NORM_EPS;
    double jerk_step = np_minimum(jerk_norm, j_max);
    double jerk_div = jerking ? jerk_norm : 1.0;
    for (int k = 0; k < 3; k++)
        acc[k] = jerking ? a_last[k] + jerk[k] / jerk_div * jerk_step * dt : a_last[k];
    /* Distance from v_last, along the acceleration's direction, to the sphere |v| = V. */
    double acc_norm = sqrt(dot3(acc, acc));
    int moving = acc_norm > NORM_EPS;
    double acc_div = moving ? acc_norm : 1.0;
    for (int k = 0; k < 3; k++) unit[k] = acc[k] / acc_div;
    double along = dot3(unit, v_last);
    double disc = along * along - dot3(v_last, v_last) + v_max * v_max;
    double distance = sqrt(np_maximum(disc, 0.0)) - along;
    double safe = np_minimum(j_max / a_max * distance, a_max);
    /* disc < 0 (v_last outside the ball): libfranka's std::min(|a|, NaN) is |a|. */
    double size = disc < 0.0 ? acc_norm : np_minimum(acc_norm, safe);
    for (int k = 0; k < 3; k++) out[k] = moving ? v_last[k] + unit[k] * size * dt : v_last[k];
}

/* limit_twist(target, ref, dref, gain, limits, out) -> bool
 *
 * target (n, 6) float64, ref / dref (n, 6) the state's O_dP_EE_c / O_ddP_EE_c (float32
 * or float64), gain the low-pass gain, limits (6,) [v, a, j, v_rot, a_rot, j_rot], out
 * (n, 6) float64. False, with out untouched, when an input is not finite: the caller's
 * numpy path then raises libfranka's error for it. */
static PyObject *limit_twist(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 6, "limit_twist") < 0) return NULL;
    enum { TARGET, REF, DREF, LIMITS, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t any6[2] = {-1, 6};
    if (f64_get(args[0], &a[TARGET], 2, any6, 0, "target") < 0) goto done;
    Py_ssize_t n = a[TARGET].shape[0];
    Py_ssize_t s6[2] = {n, 6}, l6[1] = {6};
    if (num_get(args[1], &a[REF], 2, s6, 0, "ref") < 0) goto done;
    if (num_get(args[2], &a[DREF], 2, s6, 0, "dref") < 0) goto done;
    double gain = PyFloat_AsDouble(args[3]);
    if (gain == -1.0 && PyErr_Occurred()) goto done;
    if (f64_get(args[4], &a[LIMITS], 1, l6, 0, "limits") < 0) goto done;
    if (f64_get(args[5], &a[OUT], 2, s6, 1, "out") < 0) goto done;
    const double gain_ref = 1.0 - gain;
    if (!all_finite(&a[TARGET], n, 6) || !all_finite(&a[REF], n, 6) ||
        !all_finite(&a[DREF], n, 6)) {
        result = Py_NewRef(Py_False);
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        double x[6], last[6], dlast[6], limited[6];
        for (int k = 0; k < 6; k++) {
            last[k] = num2(&a[REF], i, k);
            dlast[k] = num2(&a[DREF], i, k);
            x[k] = gain * AT2(a[TARGET], i, k) + gain_ref * last[k]; /* lowpass_core */
        }
        for (int h = 0; h < 2; h++) { /* translation, then rotation */
            limit_norm(x + 3 * h, last + 3 * h, dlast + 3 * h, AT1(a[LIMITS], 3 * h),
                       AT1(a[LIMITS], 3 * h + 1), AT1(a[LIMITS], 3 * h + 2), limited + 3 * h);
        }
        for (int k = 0; k < 6; k++) put2(&a[OUT], i, k, limited[k]);
    }
    result = Py_NewRef(Py_True);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* limit_rate(positions, target, ref, first, gain, q_d, dq_d, ddq_d, constants, shift,
 *            a_max, j_max, out)
 *
 * One cycle of libfranka's joint command path (envs/commands.py _filtered):
 *   x    = gain * target + (1 - gain) * ref      (ref = target where first[i])
 *   band = (envelope(q_d) - tolerance) - margin, as [upper | -lower]: ``shift`` is the
 *          tuple (tolerance, margin), subtracted in the reference's two steps
 *   positions: v_c = (x - q_d) / dt, limited, re-integrated q_d + v dt
 *   velocities: the limiter on x directly.
 * ref, q_d, dq_d, ddq_d may be float32 (the wire state's fields); out is float64 (the
 * command's field, any alignment). first: None or a (n,) bool array. */
static PyObject *limit_rate(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 13, "limit_rate") < 0) return NULL;
    enum { TARGET, REF, QD, DQD, DDQD, C, AMAX, JMAX, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    Py_buffer first = {0};
    PyObject *result = NULL;
    int positions = PyObject_IsTrue(args[0]);
    if (positions < 0) goto done;
    Py_ssize_t any7[2] = {-1, 7};
    if (f64_get(args[1], &a[TARGET], 2, any7, 0, "target") < 0) goto done;
    Py_ssize_t n = a[TARGET].shape[0];
    Py_ssize_t s7[2] = {n, 7}, j7[1] = {7};
    if (num_get(args[2], &a[REF], 2, s7, 0, "ref") < 0) goto done;
    if (args[3] != Py_None) {
        if (PyObject_GetBuffer(args[3], &first, PyBUF_SIMPLE) < 0) goto done;
        if (first.len != n) {
            PyErr_Format(PyExc_ValueError, "first: expected %zd bools, got %zd bytes", n,
                         first.len);
            goto done;
        }
    }
    double gain = PyFloat_AsDouble(args[4]);
    if (gain == -1.0 && PyErr_Occurred()) goto done;
    if (num_get(args[5], &a[QD], 2, s7, 0, "q_d") < 0) goto done;
    if (num_get(args[6], &a[DQD], 2, s7, 0, "dq_d") < 0) goto done;
    if (num_get(args[7], &a[DDQD], 2, s7, 0, "ddq_d") < 0) goto done;
    if (f64_get(args[8], &a[C], 2, CONSTANTS_SHAPE, 0, "constants") < 0) goto done;
    double tolerance, margin;
    if (!PyArg_ParseTuple(args[9], "dd", &tolerance, &margin)) goto done;
    if (f64_get(args[10], &a[AMAX], 1, j7, 0, "a_max") < 0) goto done;
    if (f64_get(args[11], &a[JMAX], 1, j7, 0, "j_max") < 0) goto done;
    if (f64_get(args[12], &a[OUT], 2, s7, 1, "out") < 0) goto done;
    const unsigned char *is_first = first.buf;
    const double dt = DELTA_T, gain_ref = 1.0 - gain;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) {
            double target = AT2(a[TARGET], i, j);
            double ref = is_first && is_first[i] ? target : num2(&a[REF], i, j);
            double x = gain * target + gain_ref * ref;
            double q_last = num2(&a[QD], i, j), v_last = num2(&a[DQD], i, j);
            double a_last = num2(&a[DDQD], i, j);
            double upper = envelope_entry(&a[C], j, q_last, tolerance) - margin;
            double lower = -(envelope_entry(&a[C], j + 7, q_last, tolerance) - margin);
            double a_max = AT1(a[AMAX], j), j_max = AT1(a[JMAX], j);
            /* client_filters.limit_velocities_core */
            double v_c = positions ? (x - q_last) / dt : x;
            double jerk = (((v_c - v_last) / dt) - a_last) / dt;
            double acc = a_last + np_maximum(np_minimum(jerk, j_max), -j_max) * dt;
            double ratio = j_max / a_max;
            double safe_max = np_minimum(ratio * (upper - v_last), a_max);
            double safe_min = np_maximum(ratio * (lower - v_last), -a_max);
            double v = v_last + np_maximum(np_minimum(acc, safe_max), safe_min) * dt;
            put2(&a[OUT], i, j, positions ? q_last + v * dt : v);
        }
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    if (first.obj) PyBuffer_Release(&first);
    return result;
}

/* limit_torques(target, ref, gain, dtau_max, out) -> bool
 *
 * target (n, 7) float64, ref (n, 7) the state's tau_J_d (float32 or float64), gain the
 * low-pass gain, dtau_max the limiter's rate bound [Nm/s], out (n, 7) float64:
 *   x   = gain * target + (1 - gain) * ref             (client_filters.lowpass_core)
 *   out = ref + clip((x - ref) / dt, -dtau_max, dtau_max) * dt   (limit_torques_core)
 * False, with out untouched, when an input is not finite (numpy's minimum and maximum
 * propagate a NaN, which the numpy path then does). */
static PyObject *limit_torques(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 5, "limit_torques") < 0) return NULL;
    enum { TARGET, REF, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t any7[2] = {-1, 7};
    if (f64_get(args[0], &a[TARGET], 2, any7, 0, "target") < 0) goto done;
    Py_ssize_t n = a[TARGET].shape[0];
    Py_ssize_t s7[2] = {n, 7};
    if (num_get(args[1], &a[REF], 2, s7, 0, "ref") < 0) goto done;
    double gain = PyFloat_AsDouble(args[2]);
    if (gain == -1.0 && PyErr_Occurred()) goto done;
    double d_max = PyFloat_AsDouble(args[3]);
    if (d_max == -1.0 && PyErr_Occurred()) goto done;
    if (f64_get(args[4], &a[OUT], 2, s7, 1, "out") < 0) goto done;
    if (!all_finite(&a[TARGET], n, 7) || !all_finite(&a[REF], n, 7)) {
        result = Py_NewRef(Py_False);
        goto done;
    }
    const double dt = DELTA_T, gain_ref = 1.0 - gain;
    for (Py_ssize_t i = 0; i < n; i++)
        for (int j = 0; j < 7; j++) {
            double ref = num2(&a[REF], i, j);
            double x = gain * AT2(a[TARGET], i, j) + gain_ref * ref;
            double rate = (x - ref) / dt;
            put2(&a[OUT], i, j, ref + np_maximum(np_minimum(rate, d_max), -d_max) * dt);
        }
    result = Py_NewRef(Py_True);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* ---- the Cartesian pose path: limit_pose -------------------------------------------------- */

/* client_filters._SLERP_LINEAR: Eigen's slerp interpolates linearly once |dot| >= 1 - eps. */
static const double SLERP_LINEAR = 1.0 - NORM_EPS;
/* include/franka/rate_limiting.h kFactorCartesianRotationPoseInterface. */
static const double ROTATION_POSE_FACTOR = 0.99;
/* fci/frames.py is_homogeneous allows each rotation row's and column's norm 1e-5 off 1;
 * the kernel passes squared norms only within 2e-6 of 1 and leaves anything nearer the
 * edge (never a filtered pose: those are orthonormal to rounding) to the reference. */
static const double HOMOGENEOUS_SCREEN = 2e-6;
/* A polar factor is accepted when R^T R is the identity this closely (rounding: 1e-16). */
static const double ORTHONORMAL_SCREEN = 1e-13;

/* out = R^T R of a row-major 3x3 matrix. */
static void gram3(const double *R, double *out)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += R[3 * k + r] * R[3 * k + c];
            out[3 * r + c] = s;
        }
}

/* The polar factor of a nearly orthonormal R (the float32 state's rotation), in place:
 * Newton-Schulz, R <- R (3 I - R^T R) / 2, which squares the error each time (6e-8 ->
 * 5e-15 -> rounding); commands._reference_pose takes it by SVD. 0: not converged (the
 * reference decides). */
static int polar3(double *R)
{
    double G[9], next[9];
    for (int it = 0; it < 3; it++) {
        gram3(R, G);
        for (int k = 0; k < 9; k++) G[k] = (k % 4 == 0 ? 3.0 : 0.0) - G[k];
        mat3_mul(R, G, 0, next);
        for (int k = 0; k < 9; k++) R[k] = 0.5 * next[k];
    }
    gram3(R, G);
    for (int k = 0; k < 9; k++)
        if (!(fabs(G[k] - (k % 4 == 0 ? 1.0 : 0.0)) <= ORTHONORMAL_SCREEN)) return 0;
    return 1;
}

/* client_filters._rotation_to_quaternion of one row-major rotation: Shepperd's method as
 * Eigen's Quaternion(const Matrix3&), (w, x, y, z). Row b of the symmetric K (the trace's
 * when positive, else the largest diagonal entry's, the first on ties) divided by
 * 2 sqrt(K[b, b]); the reference's _SHEPPERD_ROWS written out. */
static void rotation_to_quaternion(const double *m, double *q)
{
    double trace = m[0] + m[4] + m[8];
    int b = 0;
    if (!(trace > 0.0)) {
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

/* client_filters._quaternion_to_rotation: R[i, j] = [1 -] (P[a] +- P[b]) over the
 * products P[k, l] = (2 q_k) q_l, as Eigen's toRotationMatrix. */
static void quaternion_to_rotation(const double *q, double *R)
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

/* q . p over four values, in numpy einsum's order for "...i,...i->...". */
static inline double dot4(const double *x, const double *y)
{
    return (x[0] * y[0] + x[2] * y[2]) + (x[1] * y[1] + x[3] * y[3]);
}

/* client_filters._quaternion_slerp: Eigen's q0.slerp(t, q1). */
static void quaternion_slerp(const double *q0, const double *q1, double t, double *out)
{
    double d = dot4(q0, q1), abs_d = fabs(d), s0, s1;
    if (abs_d >= SLERP_LINEAR) {
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

/* client_filters._rotation_vector: axis * angle (angle in [0, pi]) through the
 * quaternion, Eigen's AngleAxisd. */
static void rotation_vector(const double *R, double *out)
{
    double q[4];
    rotation_to_quaternion(R, q);
    double n = sqrt(dot3(q + 1, q + 1));
    if (!(n > 0.0)) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    double angle = 2.0 * atan2(n, fabs(q[0]));
    double div = q[0] < 0.0 ? -n : n;
    for (int k = 0; k < 3; k++) out[k] = q[k + 1] / div * angle;
}

/* Whether a row-major pose passes is_homogeneous by a margin: bottom row exactly
 * [0, 0, 0, 1], each rotation row's and column's squared norm within the screen. */
static int homogeneous_screen(const double *T)
{
    if (!(T[12] == 0.0 && T[13] == 0.0 && T[14] == 0.0 && T[15] == 1.0)) return 0;
    for (int k = 0; k < 3; k++) {
        double row = T[4 * k] * T[4 * k] + T[4 * k + 1] * T[4 * k + 1] +
                     T[4 * k + 2] * T[4 * k + 2];
        double col = T[k] * T[k] + T[4 + k] * T[4 + k] + T[8 + k] * T[8 + k];
        if (!(fabs(row - 1.0) <= HOMOGENEOUS_SCREEN && fabs(col - 1.0) <= HOMOGENEOUS_SCREEN))
            return 0;
    }
    return 1;
}

/* One robot's cycle of _pose_command: the low-pass filter of the target T_c (row-major)
 * toward the reference T_ref (orthonormal), then with rate_limit the pose limiter against
 * the last twist and its rate. Writes the row-major result; 0: a screen declined. */
static int pose_cycle(const double *T_c, const double *T_ref, const double *twist_last,
                      const double *dtwist_last, double gain, const double *limits,
                      int rate_limit, double *T)
{
    /* client_filters.cartesian_lowpass_filter */
    double R_c[9], R_ref[9], q_c[4], q_ref[4], q[4], R[9];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            R_c[3 * r + c] = T_c[4 * r + c];
            R_ref[3 * r + c] = T_ref[4 * r + c];
        }
    rotation_to_quaternion(R_ref, q_ref);
    rotation_to_quaternion(R_c, q_c);
    quaternion_slerp(q_ref, q_c, gain, q);
    double norm = sqrt(dot4(q, q));
    for (int k = 0; k < 4; k++) q[k] /= norm;
    quaternion_to_rotation(q, R);
    double F[16]; /* the filtered pose */
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) F[4 * r + c] = R[3 * r + c];
        F[4 * r + 3] = gain * T_c[4 * r + 3] + (1.0 - gain) * T_ref[4 * r + 3];
    }
    for (int c = 0; c < 4; c++) F[12 + c] = T_c[12 + c];
    if (!rate_limit) {
        memcpy(T, F, sizeof(F));
        return 1;
    }
    /* client_filters.limit_rate_cartesian_pose: its input checks, then the twist */
    if (!homogeneous_screen(F)) return 0;
    const double dt = DELTA_T;
    double R_diff[9], twist[6], limited[6];
    mat3_mul(R, R_ref, 1, R_diff); /* R: the filtered pose's rotation block */
    for (int k = 0; k < 3; k++) twist[k] = (F[4 * k + 3] - T_ref[4 * k + 3]) / dt;
    rotation_vector(R_diff, twist + 3);
    for (int k = 3; k < 6; k++) twist[k] /= dt;
    limit_norm(twist, twist_last, dtwist_last, limits[0], limits[1], limits[2], limited);
    limit_norm(twist + 3, twist_last + 3, dtwist_last + 3, ROTATION_POSE_FACTOR * limits[3],
               ROTATION_POSE_FACTOR * limits[4], ROTATION_POSE_FACTOR * limits[5],
               limited + 3);
    /* integrated over one cycle: Rodrigues about w / |w| by |w| dt, on the left */
    const double *w = limited + 3;
    double w_norm = sqrt(dot3(w, w));
    double R_out[9];
    if (w_norm > NORM_EPS) {
        double axis[3], theta = dt * w_norm;
        for (int k = 0; k < 3; k++) axis[k] = w[k] / w_norm;
        rotate_left(axis, sin(theta), 1.0 - cos(theta), R_ref, R_out);
    } else {
        memcpy(R_out, R_ref, sizeof(R_out));
    }
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) T[4 * r + c] = R_out[3 * r + c];
        T[4 * r + 3] = T_ref[4 * r + 3] + limited[r] * dt;
    }
    T[12] = T[13] = T[14] = 0.0;
    T[15] = 1.0;
    return 1;
}

/* limit_pose(target, ref, dref, ddref, gain, limits, rate_limit, out) -> bool
 *
 * target (n, 4, 4) float64 row-major (the step's target pose), ref (n, 16) the state's
 * column-major O_T_EE_c, dref / ddref (n, 6) its O_dP_EE_c / O_ddP_EE_c (ref, dref and
 * ddref float32 or float64), gain the low-pass gain, limits (6,) [v, a, j, v_rot, a_rot,
 * j_rot] (the rotational ones unscaled, as the reference takes them), out (n, 16)
 * float64, column-major (the command's wire layout). False where the reference would
 * raise (a non-finite input, a filtered pose that is no homogeneous transform) or a screen
 * declines (a reference rotation far from orthonormal): out is then not to be used, and
 * the caller takes the numpy path, which names the error. */
static PyObject *limit_pose(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 8, "limit_pose") < 0) return NULL;
    enum { TARGET, REF, DREF, DDREF, LIMITS, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t any44[3] = {-1, 4, 4};
    if (f64_get(args[0], &a[TARGET], 3, any44, 0, "target") < 0) goto done;
    Py_ssize_t n = a[TARGET].shape[0];
    Py_ssize_t s16[2] = {n, 16}, s6[2] = {n, 6}, l6[1] = {6};
    if (num_get(args[1], &a[REF], 2, s16, 0, "ref") < 0) goto done;
    if (num_get(args[2], &a[DREF], 2, s6, 0, "dref") < 0) goto done;
    if (num_get(args[3], &a[DDREF], 2, s6, 0, "ddref") < 0) goto done;
    double gain = PyFloat_AsDouble(args[4]);
    if (gain == -1.0 && PyErr_Occurred()) goto done;
    if (f64_get(args[5], &a[LIMITS], 1, l6, 0, "limits") < 0) goto done;
    int rate_limit = PyObject_IsTrue(args[6]);
    if (rate_limit < 0) goto done;
    if (f64_get(args[7], &a[OUT], 2, s16, 1, "out") < 0) goto done;
    double limits[6];
    for (int k = 0; k < 6; k++) limits[k] = AT1(a[LIMITS], k);
    result = Py_NewRef(Py_True);
    for (Py_ssize_t i = 0; i < n; i++) {
        double T_c[16], T_ref[16], twist_last[6], dtwist_last[6], T[16];
        int finite = 1;
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) {
                T_c[4 * r + c] = AT3(a[TARGET], i, r, c);
                T_ref[4 * r + c] = num2(&a[REF], i, 4 * c + r); /* fci.frames.from_wire */
                finite &= isfinite(T_c[4 * r + c]) && isfinite(T_ref[4 * r + c]);
            }
        for (int k = 0; k < 6; k++) {
            twist_last[k] = num2(&a[DREF], i, k);
            dtwist_last[k] = num2(&a[DDREF], i, k);
            finite &= isfinite(twist_last[k]) && isfinite(dtwist_last[k]);
        }
        /* commands._reference_pose: the reference's rotation re-orthonormalised */
        double R_ref[9];
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) R_ref[3 * r + c] = T_ref[4 * r + c];
        if (!finite || !polar3(R_ref)) goto decline;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) T_ref[4 * r + c] = R_ref[3 * r + c];
        if (!pose_cycle(T_c, T_ref, twist_last, dtwist_last, gain, limits, rate_limit, T))
            goto decline;
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) AT2(a[OUT], i, 4 * c + r) = T[4 * r + c]; /* to_wire */
    }
    goto done;
decline:
    Py_SETREF(result, Py_NewRef(Py_False));
done:
    f64_release_all(a, COUNT);
    return result;
}

static PyMethodDef METHODS[] = {
    {"limit_rate", (PyCFunction)(void (*)(void))limit_rate, METH_FASTCALL,
     "limit_rate(positions, target, ref, first, gain, q_d, dq_d, ddq_d, constants, "
     "(tolerance, margin), a_max, j_max, out): libfranka's joint low-pass and rate limiter."},
    {"limit_twist", (PyCFunction)(void (*)(void))limit_twist, METH_FASTCALL,
     "limit_twist(target, ref, dref, gain, limits, out) -> bool: libfranka's low-pass "
     "filter and Cartesian velocity rate limiter (False: a non-finite input, nothing done)."},
    {"limit_torques", (PyCFunction)(void (*)(void))limit_torques, METH_FASTCALL,
     "limit_torques(target, ref, gain, dtau_max, out) -> bool: libfranka's low-pass filter "
     "and torque rate limiter (False: a non-finite input, nothing done)."},
    {"limit_pose", (PyCFunction)(void (*)(void))limit_pose, METH_FASTCALL,
     "limit_pose(target, ref, dref, ddref, gain, limits, rate_limit, out) -> bool: libfranka's "
     "Cartesian low-pass filter and pose rate limiter (False: the numpy path decides)."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_client_filters,
              "The env client's libfranka filters (fused copies of numpy reference code).")
