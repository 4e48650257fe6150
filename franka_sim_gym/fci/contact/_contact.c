/* The contact estimate's and the collision levels' rules: their only text (issue 38: one
 * text per rule, compiled; fci/contact/estimate.py, fci/contact/sensing.py and fci/contact/collision.py hand
 * them the state and the constants). Every constant (the filter's gain, the damping, the
 * published decimals, collision.py's acceleration phase) is an argument:
 *
 *   filter_residual(tau_ext, tau_J, m_ddq, bias, alpha, decimals, out)
 *       tau_ext += alpha (tau_J - (m_ddq + bias) - tau_ext), in place; out its rounding
 *   wrench_from_torque(jacobian, tau, damping, decimals, out)
 *       the least-squares wrench (J J^T + damping I) F = J tau, rounded
 *   in_frame(wrench, rotation, decimals, out)
 *       [f R, m R] (R^T f, R^T m), rounded
 *   k_frame(O_T_EE, EE_T_K, point, rotation)
 *       K's origin and axes in the base frame, O_T_K = O_T_EE EE_T_K
 *   sense(...)
 *       fci/contact/sensing.py's step after the model terms, one call per cycle: the three
 *       rules above per robot, then the collision levels (collision.py's thresholds and
 *       phases) on the published values: the contact flags, the flags over an upper
 *       threshold and the phase written, the robots over one counted
 *
 * Rounding is numpy's np.round: rint(x 10^d) / 10^d; the wrenches publish a negative zero
 * as zero. Built without fused multiply-adds (setup.py). The 6 x 6 solve is an
 * elimination with partial pivoting (_solve6.h). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_solve6.h"

/* An int argument >= 0 (the decimals), as the power of ten numpy's round scales by. */
static int scale_get(PyObject *obj, double *scale)
{
    long d = PyLong_AsLong(obj);
    if (d == -1 && PyErr_Occurred()) return -1;
    if (d < 0 || d > 22) {
        PyErr_SetString(PyExc_ValueError, "decimals: expected 0 to 22");
        return -1;
    }
    double s = 1.0;
    for (long k = 0; k < d; k++) s *= 10.0; /* exact up to 10^22 */
    *scale = s;
    return 0;
}

static int double_get(PyObject *obj, double *out, const char *name)
{
    *out = PyFloat_AsDouble(obj);
    if (*out == -1.0 && PyErr_Occurred()) {
        PyErr_Format(PyExc_TypeError, "%s: expected a number", name);
        return -1;
    }
    return 0;
}

/* np.round(x, d): multiply, rint, divide. */
static inline double rounded(double x, double scale)
{
    return rint(x * scale) / scale;
}

/* rounded, then + 0.0: no negative zero (the wrench's). */
static inline double published(double x, double scale)
{
    return rounded(x, scale) + 0.0;
}

/* ---- one robot's row of each rule (the functions below loop them) ------------------- */

/* The filter step of robot i, in place on tau_ext; ``out`` its rounding. */
static inline void filter_row(F64 *tau_ext, const F64 *tau_J, const F64 *m_ddq, const F64 *bias,
                              Py_ssize_t i, double alpha, double scale, double out[7])
{
    for (int j = 0; j < 7; j++) {
        double residual = num2(tau_J, i, j) - (num2(m_ddq, i, j) + num2(bias, i, j));
        double tau = AT2(*tau_ext, i, j);
        tau += alpha * (residual - tau);
        AT2(*tau_ext, i, j) = tau;
        out[j] = rounded(tau, scale);
    }
}

/* The published wrench of robot i: (J J^T + damping I) F = J tau, rounded. */
static inline void wrench_row(const F64 *jac, Py_ssize_t i, const double tau[7], double damping,
                              double scale, double out[6])
{
    double J[6][7], A[6][6], b[6];
    for (int r = 0; r < 6; r++)
        for (int k = 0; k < 7; k++) J[r][k] = AT3(*jac, i, r, k);
    for (int r = 0; r < 6; r++) {
        for (int c = r; c < 6; c++) { /* J J^T is symmetric: one triangle */
            double s = 0.0;
            for (int k = 0; k < 7; k++) s += J[r][k] * J[c][k];
            A[r][c] = A[c][r] = s;
        }
        A[r][r] += damping;
        double s = 0.0;
        for (int k = 0; k < 7; k++) s += J[r][k] * tau[k];
        b[r] = s;
    }
    solve6(A, b);
    for (int r = 0; r < 6; r++) out[r] = published(b[r], scale);
}

/* Robot i's wrench ``w`` in the axes of its rotation: [f R, m R], rounded. */
static inline void frame_row(const F64 *rot, Py_ssize_t i, const double w[6], double scale,
                             double out[6])
{
    for (int half = 0; half < 2; half++)
        for (int c = 0; c < 3; c++) {
            const double *v = w + 3 * half;
            double s = v[0] * AT3(*rot, i, 0, c) + v[1] * AT3(*rot, i, 1, c) +
                       v[2] * AT3(*rot, i, 2, c);
            out[3 * half + c] = published(s, scale);
        }
}

/* filter_residual(tau_ext, tau_J, m_ddq, bias, alpha, decimals, out): (n, 7) each. */
static PyObject *filter_residual(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { TAU_EXT, TAU_J, M_DDQ, BIAS, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double alpha, scale;
    if (check_nargs(nargs, 7, "filter_residual") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "tau_ext");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7};
    if (f64_get(args[0], &a[TAU_EXT], 2, s7, 1, "tau_ext") < 0 ||
        num_get(args[1], &a[TAU_J], 2, s7, 0, "tau_J") < 0 ||
        num_get(args[2], &a[M_DDQ], 2, s7, 0, "m_ddq") < 0 ||
        num_get(args[3], &a[BIAS], 2, s7, 0, "bias") < 0 ||
        double_get(args[4], &alpha, "alpha") < 0 || scale_get(args[5], &scale) < 0 ||
        f64_get(args[6], &a[OUT], 2, s7, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double tau[7];
        filter_row(&a[TAU_EXT], &a[TAU_J], &a[M_DDQ], &a[BIAS], i, alpha, scale, tau);
        for (int j = 0; j < 7; j++) AT2(a[OUT], i, j) = tau[j];
    }
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* wrench_from_torque(jacobian, tau, damping, decimals, out): (n, 6, 7), (n, 7), float,
 * int, (n, 6). */
static PyObject *wrench_from_torque(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { JAC, TAU, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double damping, scale;
    if (check_nargs(nargs, 5, "wrench_from_torque") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "jacobian");
    if (n < 0) return NULL;
    Py_ssize_t s67[3] = {n, 6, 7}, s7[2] = {n, 7}, s6[2] = {n, 6};
    if (f64_get(args[0], &a[JAC], 3, s67, 0, "jacobian") < 0 ||
        num_get(args[1], &a[TAU], 2, s7, 0, "tau") < 0 ||
        double_get(args[2], &damping, "damping") < 0 || scale_get(args[3], &scale) < 0 ||
        f64_get(args[4], &a[OUT], 2, s6, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double tau[7], w[6];
        for (int k = 0; k < 7; k++) tau[k] = num2(&a[TAU], i, k);
        wrench_row(&a[JAC], i, tau, damping, scale, w);
        for (int r = 0; r < 6; r++) AT2(a[OUT], i, r) = w[r];
    }
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* in_frame(wrench, rotation, decimals, out): (n, 6), (n, 3, 3), int, (n, 6). */
static PyObject *in_frame(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { WRENCH, ROT, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double scale;
    if (check_nargs(nargs, 4, "in_frame") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "wrench");
    if (n < 0) return NULL;
    Py_ssize_t s6[2] = {n, 6}, s33[3] = {n, 3, 3};
    if (num_get(args[0], &a[WRENCH], 2, s6, 0, "wrench") < 0 ||
        f64_get(args[1], &a[ROT], 3, s33, 0, "rotation") < 0 || scale_get(args[2], &scale) < 0 ||
        f64_get(args[3], &a[OUT], 2, s6, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double w[6], k[6];
        for (int c = 0; c < 6; c++) w[c] = num2(&a[WRENCH], i, c);
        frame_row(&a[ROT], i, w, scale, k);
        for (int c = 0; c < 6; c++) AT2(a[OUT], i, c) = k[c];
    }
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* k_frame(O_T_EE, EE_T_K, point, rotation): (n, 16) wire poses (column-major: element
 * (r, c) at 4 c + r) to K's origin (n, 3) p_EE + R_EE t_K and axes (n, 3, 3) R_EE R_K. */
static PyObject *k_frame(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { O_T_EE, EE_T_K, POINT, ROT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    if (check_nargs(nargs, 4, "k_frame") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "O_T_EE");
    if (n < 0) return NULL;
    Py_ssize_t s16[2] = {n, 16}, s3[2] = {n, 3}, s33[3] = {n, 3, 3};
    if (num_get(args[0], &a[O_T_EE], 2, s16, 0, "O_T_EE") < 0 ||
        num_get(args[1], &a[EE_T_K], 2, s16, 0, "EE_T_K") < 0 ||
        f64_get(args[2], &a[POINT], 2, s3, 1, "point") < 0 ||
        f64_get(args[3], &a[ROT], 3, s33, 1, "rotation") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double T[16], E[16];
        for (int k = 0; k < 16; k++) {
            T[k] = num2(&a[O_T_EE], i, k);
            E[k] = num2(&a[EE_T_K], i, k);
        }
        for (int r = 0; r < 3; r++) {
            AT2(a[POINT], i, r) = T[12 + r] + T[r] * E[12] + T[4 + r] * E[13] + T[8 + r] * E[14];
            for (int c = 0; c < 3; c++)
                AT3(a[ROT], i, r, c) =
                    T[r] * E[4 * c] + T[4 + r] * E[4 * c + 1] + T[8 + r] * E[4 * c + 2];
        }
    }
    result = Py_None;
    Py_INCREF(result);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* The columns of one phase's thresholds (fci/contact/collision.py CollisionBehavior.thresholds). */
enum { LOWER_TORQUE = 0, UPPER_TORQUE = 7, LOWER_FORCE = 14, UPPER_FORCE = 20, THRESHOLDS = 26 };

/* sense(tau_ext, tau_J, m_ddq, bias, jacobian, rotation, ddq_d, in_motion, thresholds,
 *       alpha, damping, decimals, acceleration_phase,
 *       tau, wrench, k_wrench, joint_contact, cartesian_contact,
 *       joint_over, cartesian_over, accelerating) -> int
 * The whole step of fci/contact/sensing.py ContactSensing.sense after the model terms:
 * filter_residual into tau, wrench_from_torque into wrench, in_frame into k_wrench, then
 * the collision levels (fci/contact/collision.py: SetCollisionBehavior's thresholds) on the
 * published tau and wrench. A robot is in its acceleration phase when it is in motion and
 * some |ddq_d| is above ``acceleration_phase`` (a NaN is not); each |tau_j| and |F_c| is
 * compared with its lower threshold (``*_contact``, 1.0 / 0.0) and its upper one
 * (``*_over``, 1.0 / 0.0) of that phase, strictly ("above": a value at a threshold is
 * not, a NaN never is). Returns the number of robots over an upper threshold. (n, 7) /
 * (n, 6) each; jacobian (n, 6, 7), rotation (n, 3, 3), in_motion (n,) bool, thresholds
 * (n, 2, 26), accelerating (n,) uint8 written. */
static PyObject *sense(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { TAU_EXT, TAU_J, M_DDQ, BIAS, JAC, ROT, DDQ_D, LIMITS, TAU, WRENCH, K_WRENCH,
           JOINT_CONTACT, CARTESIAN_CONTACT, JOINT_OVER, CARTESIAN_OVER, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    Bytes in_motion, phase_out;
    memset(&in_motion, 0, sizeof(in_motion));
    memset(&phase_out, 0, sizeof(phase_out));
    PyObject *result = NULL;
    double alpha, damping, scale, phase_bound;
    if (check_nargs(nargs, 21, "sense") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "tau_ext");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, s6[2] = {n, 6}, s67[3] = {n, 6, 7}, s33[3] = {n, 3, 3},
               sl[3] = {n, 2, THRESHOLDS};
    if (f64_get(args[0], &a[TAU_EXT], 2, s7, 1, "tau_ext") < 0 ||
        num_get(args[1], &a[TAU_J], 2, s7, 0, "tau_J") < 0 ||
        num_get(args[2], &a[M_DDQ], 2, s7, 0, "m_ddq") < 0 ||
        num_get(args[3], &a[BIAS], 2, s7, 0, "bias") < 0 ||
        f64_get(args[4], &a[JAC], 3, s67, 0, "jacobian") < 0 ||
        f64_get(args[5], &a[ROT], 3, s33, 0, "rotation") < 0 ||
        num_get(args[6], &a[DDQ_D], 2, s7, 0, "ddq_d") < 0 ||
        bytes_get(args[7], &in_motion, n, 0, "in_motion") < 0 ||
        f64_get(args[8], &a[LIMITS], 3, sl, 0, "thresholds") < 0 ||
        double_get(args[9], &alpha, "alpha") < 0 ||
        double_get(args[10], &damping, "damping") < 0 || scale_get(args[11], &scale) < 0 ||
        double_get(args[12], &phase_bound, "acceleration_phase") < 0 ||
        f64_get(args[13], &a[TAU], 2, s7, 1, "tau") < 0 ||
        f64_get(args[14], &a[WRENCH], 2, s6, 1, "wrench") < 0 ||
        f64_get(args[15], &a[K_WRENCH], 2, s6, 1, "k_wrench") < 0 ||
        f64_get(args[16], &a[JOINT_CONTACT], 2, s7, 1, "joint_contact") < 0 ||
        f64_get(args[17], &a[CARTESIAN_CONTACT], 2, s6, 1, "cartesian_contact") < 0 ||
        f64_get(args[18], &a[JOINT_OVER], 2, s7, 1, "joint_over") < 0 ||
        f64_get(args[19], &a[CARTESIAN_OVER], 2, s6, 1, "cartesian_over") < 0 ||
        bytes_get(args[20], &phase_out, n, 1, "accelerating") < 0)
        goto done;
    long over = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        double tau[7], w[6], k[6];
        filter_row(&a[TAU_EXT], &a[TAU_J], &a[M_DDQ], &a[BIAS], i, alpha, scale, tau);
        wrench_row(&a[JAC], i, tau, damping, scale, w);
        frame_row(&a[ROT], i, w, scale, k);
        /* the acceleration phase: in motion and some |ddq_d| above the bound (a NaN is not) */
        int accelerating = 0;
        if (BYTE1(in_motion, i))
            for (int j = 0; j < 7; j++) accelerating |= fabs(num2(&a[DDQ_D], i, j)) > phase_bound;
        phase_out.data[i * phase_out.stride] = (char)accelerating;
        int p = accelerating ? 0 : 1; /* thresholds: phase 0 acceleration, 1 nominal */
        int crossed = 0;
        for (int j = 0; j < 7; j++) {
            double size = fabs(tau[j]);
            int hit = size > AT3(a[LIMITS], i, p, UPPER_TORQUE + j);
            AT2(a[TAU], i, j) = tau[j];
            AT2(a[JOINT_CONTACT], i, j) = size > AT3(a[LIMITS], i, p, LOWER_TORQUE + j);
            AT2(a[JOINT_OVER], i, j) = hit;
            crossed |= hit;
        }
        for (int c = 0; c < 6; c++) {
            double size = fabs(w[c]);
            int hit = size > AT3(a[LIMITS], i, p, UPPER_FORCE + c);
            AT2(a[WRENCH], i, c) = w[c];
            AT2(a[K_WRENCH], i, c) = k[c];
            AT2(a[CARTESIAN_CONTACT], i, c) = size > AT3(a[LIMITS], i, p, LOWER_FORCE + c);
            AT2(a[CARTESIAN_OVER], i, c) = hit;
            crossed |= hit;
        }
        over += crossed;
    }
    result = PyLong_FromLong(over);
done:
    f64_release_all(a, COUNT);
    bytes_release(&in_motion);
    bytes_release(&phase_out);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(filter_residual, "One step of the estimate's filter, out given."),
    METHOD(wrench_from_torque, "The wrench at the Jacobian's point, out given."),
    METHOD(in_frame, "A wrench in a frame's axes, out given."),
    METHOD(k_frame, "The frame K from O_T_EE and EE_T_K."),
    METHOD(sense, "A cycle's estimate, wrench at K, contact and collision levels."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_contact, "The contact estimate's and the collision levels' rules: their only text (fci/).")
