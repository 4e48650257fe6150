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
 *
 * Elementwise arithmetic in the reference's order, built without fused multiply-adds
 * (setup.py); the twist limiter's 3-vector dot products sum as numpy's einsum sums
 * three products, (x0 y0 + x2 y2) + x1 y1, so the result is the reference's bits
 * (tests/test_native_client.py, tests/test_native_joint.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_envelope.h"

#define DELTA_T KERNEL_DT

/* client_filters._NORM_EPS: libfranka's kNormEps, float64 machine epsilon. */
static const double NORM_EPS = 2.220446049250313e-16;

/* x . y over three values, summed in numpy einsum's order for "...i,...i->...". */
static inline double dot3(const double *x, const double *y)
{
    return (x[0] * y[0] + x[2] * y[2]) + x[1] * y[1];
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
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int k = 0; k < 6; k++) {
            if (!isfinite(AT2(a[TARGET], i, k)) || !isfinite(num2(&a[REF], i, k)) ||
                !isfinite(num2(&a[DREF], i, k))) {
                result = Py_NewRef(Py_False);
                goto done;
            }
        }
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

static PyMethodDef METHODS[] = {
    {"limit_rate", (PyCFunction)(void (*)(void))limit_rate, METH_FASTCALL,
     "limit_rate(positions, target, ref, first, gain, q_d, dq_d, ddq_d, constants, "
     "(tolerance, margin), a_max, j_max, out): libfranka's joint low-pass and rate limiter."},
    {"limit_twist", (PyCFunction)(void (*)(void))limit_twist, METH_FASTCALL,
     "limit_twist(target, ref, dref, gain, limits, out) -> bool: libfranka's low-pass "
     "filter and Cartesian velocity rate limiter (False: a non-finite input, nothing done)."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_client_filters,
              "The env client's libfranka filters (fused copies of numpy reference code).")
