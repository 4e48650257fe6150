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
#include <stdio.h>

#include "_arrays.h"
#include "_jacobian.h"
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

/* Robot i's frame K: origin p_EE + R_EE t_K into point[i], axes R_EE R_K into rotation[i]. */
static inline void k_frame_row(const F64 *O_T_EE, const F64 *EE_T_K, Py_ssize_t i, F64 *point,
                               F64 *rotation)
{
    double T[16], E[16];
    for (int k = 0; k < 16; k++) {
        T[k] = num2(O_T_EE, i, k);
        E[k] = num2(EE_T_K, i, k);
    }
    for (int r = 0; r < 3; r++) {
        AT2(*point, i, r) = T[12 + r] + T[r] * E[12] + T[4 + r] * E[13] + T[8 + r] * E[14];
        for (int c = 0; c < 3; c++)
            AT3(*rotation, i, r, c) =
                T[r] * E[4 * c] + T[4 + r] * E[4 * c + 1] + T[8 + r] * E[4 * c + 2];
    }
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
    for (Py_ssize_t i = 0; i < n; i++) k_frame_row(&a[O_T_EE], &a[EE_T_K], i, &a[POINT], &a[ROT]);
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
/* What sense_row reads and writes (the arrays of sense's arguments, or of a plan). */
typedef struct {
    F64 *tau_ext;
    const F64 *tau_J, *m_ddq, *bias, *jacobian, *rotation, *ddq_d;
    const Bytes *in_motion;
    const F64 *thresholds;
    double alpha, damping, scale, phase_bound;
    F64 *tau, *wrench, *k_wrench, *joint_contact, *cartesian_contact, *joint_over,
        *cartesian_over;
    Bytes *accelerating;
} SenseRow;

/* Robot i's estimate, wrench at K and in K's axes, and collision levels (sense's rules);
 * 1 where it crossed an upper threshold. */
static inline int sense_row(const SenseRow *r, Py_ssize_t i)
{
    double tau[7], w[6], k[6];
    filter_row(r->tau_ext, r->tau_J, r->m_ddq, r->bias, i, r->alpha, r->scale, tau);
    wrench_row(r->jacobian, i, tau, r->damping, r->scale, w);
    frame_row(r->rotation, i, w, r->scale, k);
    /* the acceleration phase: in motion and some |ddq_d| above the bound (a NaN is not) */
    int accelerating = 0;
    if (BYTE1(*r->in_motion, i))
        for (int j = 0; j < 7; j++) accelerating |= fabs(num2(r->ddq_d, i, j)) > r->phase_bound;
    r->accelerating->data[i * r->accelerating->stride] = (char)accelerating;
    int p = accelerating ? 0 : 1; /* thresholds: phase 0 acceleration, 1 nominal */
    int crossed = 0;
    for (int j = 0; j < 7; j++) {
        double size = fabs(tau[j]);
        int hit = size > AT3(*r->thresholds, i, p, UPPER_TORQUE + j);
        AT2(*r->tau, i, j) = tau[j];
        AT2(*r->joint_contact, i, j) = size > AT3(*r->thresholds, i, p, LOWER_TORQUE + j);
        AT2(*r->joint_over, i, j) = hit;
        crossed |= hit;
    }
    for (int c = 0; c < 6; c++) {
        double size = fabs(w[c]);
        int hit = size > AT3(*r->thresholds, i, p, UPPER_FORCE + c);
        AT2(*r->wrench, i, c) = w[c];
        AT2(*r->k_wrench, i, c) = k[c];
        AT2(*r->cartesian_contact, i, c) = size > AT3(*r->thresholds, i, p, LOWER_FORCE + c);
        AT2(*r->cartesian_over, i, c) = hit;
        crossed |= hit;
    }
    return crossed;
}

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
    SenseRow r = {&a[TAU_EXT], &a[TAU_J], &a[M_DDQ], &a[BIAS], &a[JAC], &a[ROT], &a[DDQ_D],
                  &in_motion, &a[LIMITS], alpha, damping, scale, phase_bound, &a[TAU],
                  &a[WRENCH], &a[K_WRENCH], &a[JOINT_CONTACT], &a[CARTESIAN_CONTACT],
                  &a[JOINT_OVER], &a[CARTESIAN_OVER], &phase_out};
    long over = 0;
    for (Py_ssize_t i = 0; i < n; i++) over += sense_row(&r, i);
    result = PyLong_FromLong(over);
done:
    f64_release_all(a, COUNT);
    bytes_release(&in_motion);
    bytes_release(&phase_out);
    return result;
}


/* ---- the whole sensing step, planned (fci/contact/sensing.py ContactSensing.sense) ---- */

/* Sensing(qM, block, qfrc_bias, passive, payload, dq, dq_prev, mass, bias, O_T_EE, EE_T_K,
 *         axes, anchors, point, rotation, jacobian, tau_J, ddq_d, thresholds, tau_ext,
 *         m_ddq, loaded, tau, wrench, k_wrench, joint_contact, cartesian_contact,
 *         joint_over, cartesian_over, accelerating, constants)
 * holds every array of a cycle's sensing; run(in_motion, load) -> int is the step:
 *   - the model terms of the new state: M gathered out of each arm's stretch of MuJoCo's
 *     sparse inertia (qM (n, L), block (49,) int64 indices into it, row-major), the bias
 *     C dq + g + friction = qfrc_bias - passive (- payload (n, 7), a payload the robot's
 *     model does not know of, or None);
 *   - the estimator's terms of the step that ended (estimate.py ExternalTorqueEstimator):
 *     ddq = (dq - dq_prev) / cycle, m_ddq = mass ddq (the M of the state the step started
 *     from, summed j = 0..6 in order), loaded = bias (+ load (n, 7), a configured load's
 *     weight, or None); then dq_prev, mass and bias become the new state's;
 *   - K's frame (point, rotation) from O_T_EE and EE_T_K (n, 16) and the Jacobian at K
 *     (axes, anchors (n, 7, 3): native/_jacobian.h);
 *   - sense's rules on them (sense_row), in_motion (n,) bool this cycle's;
 * reset(robots) restarts their estimate at the state their arms are at.
 * constants: (alpha, damping, decimals, acceleration_phase, cycle). */
enum {
    S_QM, S_BLOCK, S_QFRC_BIAS, S_PASSIVE, S_PAYLOAD, S_DQ, S_DQ_PREV, S_MASS, S_BIAS,
    S_O_T_EE, S_EE_T_K, S_AXES, S_ANCHORS, S_POINT, S_ROT, S_JAC, S_TAU_J, S_DDQ_D,
    S_LIMITS, S_TAU_EXT, S_M_DDQ, S_LOADED, S_TAU, S_WRENCH, S_K_WRENCH, S_JOINT_CONTACT,
    S_CARTESIAN_CONTACT, S_JOINT_OVER, S_CARTESIAN_OVER, S_ACCELERATING, S_CONSTANTS,
    S_COUNT
};

typedef struct {
    PyObject_HEAD
    Py_ssize_t n, stretch;
    F64 a[S_COUNT]; /* the float64 arrays, by their S_ index (block, payload,
                       accelerating and constants unused) */
    Py_ssize_t block[49];
    int payload;
    Bytes accelerating;
    double alpha, damping, scale, phase_bound, cycle;
} SensingObject;

static void Sensing_dealloc(SensingObject *self)
{
    f64_release_all(self->a, S_COUNT);
    bytes_release(&self->accelerating);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static const char *const SENSING_NAMES[S_COUNT] = {
    "qM", "block", "qfrc_bias", "passive", "payload", "dq", "dq_prev", "mass", "bias",
    "O_T_EE", "EE_T_K", "axes", "anchors", "point", "rotation", "jacobian", "tau_J", "ddq_d",
    "thresholds", "tau_ext", "m_ddq", "loaded", "tau", "wrench", "k_wrench", "joint_contact",
    "cartesian_contact", "joint_over", "cartesian_over", "accelerating", "constants"};

static PyObject *Sensing_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "Sensing() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), S_COUNT, "Sensing") < 0) return NULL;
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    Py_ssize_t n = leading(v[S_QM], "qM");
    if (n < 0) return NULL;
    SensingObject *self = (SensingObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    Py_ssize_t anyL[2] = {n, -1}, s7[2] = {n, 7}, s77[3] = {n, 7, 7}, s16[2] = {n, 16},
               s73[3] = {n, 7, 3}, s3[2] = {n, 3}, s33[3] = {n, 3, 3}, s67[3] = {n, 6, 7},
               s6[2] = {n, 6}, sl[3] = {n, 2, THRESHOLDS};
    /* each float64 array: its shape, writable, float32 accepted (the wire's fields) */
    struct { int k, ndim; const Py_ssize_t *shape; int writable, any_float; } specs[] = {
        {S_QM, 2, anyL, 0, 0},         {S_QFRC_BIAS, 2, s7, 0, 0}, {S_PASSIVE, 2, s7, 0, 0},
        {S_DQ, 2, s7, 0, 0},           {S_DQ_PREV, 2, s7, 1, 0},   {S_MASS, 3, s77, 1, 0},
        {S_BIAS, 2, s7, 1, 0},         {S_O_T_EE, 2, s16, 0, 1},   {S_EE_T_K, 2, s16, 0, 1},
        {S_AXES, 3, s73, 0, 0},        {S_ANCHORS, 3, s73, 0, 0},  {S_POINT, 2, s3, 1, 0},
        {S_ROT, 3, s33, 1, 0},         {S_JAC, 3, s67, 1, 0},      {S_TAU_J, 2, s7, 0, 1},
        {S_DDQ_D, 2, s7, 0, 1},        {S_LIMITS, 3, sl, 0, 0},    {S_TAU_EXT, 2, s7, 1, 0},
        {S_M_DDQ, 2, s7, 1, 0},        {S_LOADED, 2, s7, 1, 0},    {S_TAU, 2, s7, 1, 0},
        {S_WRENCH, 2, s6, 1, 0},       {S_K_WRENCH, 2, s6, 1, 0},  {S_JOINT_CONTACT, 2, s7, 1, 0},
        {S_CARTESIAN_CONTACT, 2, s6, 1, 0}, {S_JOINT_OVER, 2, s7, 1, 0},
        {S_CARTESIAN_OVER, 2, s6, 1, 0},
    };
    for (size_t k = 0; k < sizeof(specs) / sizeof(specs[0]); k++) {
        int at = specs[k].k;
        if (borrow(v[at], &self->a[at], specs[k].ndim, specs[k].shape, specs[k].writable,
                   SENSING_NAMES[at], specs[k].any_float) < 0)
            goto fail;
    }
    self->stretch = self->a[S_QM].shape[1];
    self->payload = v[S_PAYLOAD] != Py_None;
    if (self->payload && f64_get(v[S_PAYLOAD], &self->a[S_PAYLOAD], 2, s7, 0, "payload") < 0)
        goto fail;
    Int64s block;
    if (int64s_get(v[S_BLOCK], &block, 49, 0, "block") < 0) goto fail;
    for (int k = 0; k < 49; k++) {
        long long at = INT64_AT(block, k);
        if (at < 0 || at >= self->stretch) {
            int64s_release(&block);
            PyErr_Format(PyExc_ValueError, "block[%d]: %lld is outside qM's %zd columns", k, at,
                         self->stretch);
            goto fail;
        }
        self->block[k] = (Py_ssize_t)at;
    }
    int64s_release(&block);
    if (bytes_get(v[S_ACCELERATING], &self->accelerating, n, 1, "accelerating") < 0) goto fail;
    PyObject *c = v[S_CONSTANTS];
    if (!PyTuple_Check(c) || PyTuple_GET_SIZE(c) != 5) {
        PyErr_SetString(PyExc_TypeError, "constants: expected a tuple (alpha, damping, "
                                         "decimals, acceleration_phase, cycle)");
        goto fail;
    }
    if (double_get(PyTuple_GET_ITEM(c, 0), &self->alpha, "alpha") < 0 ||
        double_get(PyTuple_GET_ITEM(c, 1), &self->damping, "damping") < 0 ||
        scale_get(PyTuple_GET_ITEM(c, 2), &self->scale) < 0 ||
        double_get(PyTuple_GET_ITEM(c, 3), &self->phase_bound, "acceleration_phase") < 0 ||
        double_get(PyTuple_GET_ITEM(c, 4), &self->cycle, "cycle") < 0)
        goto fail;
    if (!(self->cycle > 0.0)) {
        char text[64];
        snprintf(text, sizeof(text), "cycle: %g is not a positive duration", self->cycle);
        PyErr_SetString(PyExc_ValueError, text);
        goto fail;
    }
    return (PyObject *)self;
fail:
    Py_DECREF(self);
    return NULL;
}

/* Robot i's model terms of the state its arm is at: M gathered out of its stretch of the
 * sparse inertia into mass[i], the bias qfrc_bias - passive (- payload) into bias[i]. */
static inline void model_terms_row(SensingObject *self, Py_ssize_t i)
{
    F64 *a = self->a;
    for (int k = 0; k < 49; k++) AT3(a[S_MASS], i, k / 7, k % 7) = AT2(a[S_QM], i, self->block[k]);
    for (int j = 0; j < 7; j++) {
        double bias = AT2(a[S_QFRC_BIAS], i, j) - AT2(a[S_PASSIVE], i, j);
        AT2(a[S_BIAS], i, j) = self->payload ? bias - AT2(a[S_PAYLOAD], i, j) : bias;
    }
}

/* Sensing.reset(robots): the estimate of ``robots`` ((k,) int64) restarts from zero at the
 * state their arms are at (a teleport: a velocity jump is no acceleration). */
static PyObject *Sensing_reset(SensingObject *self, PyObject *robots)
{
    Int64s view;
    Py_ssize_t count = leading(robots, "robots");
    if (count < 0 || int64s_get(robots, &view, count, 0, "robots") < 0) return NULL;
    for (Py_ssize_t k = 0; k < count; k++) {
        long long r = INT64_AT(view, k);
        if (r < 0 || r >= self->n) {
            int64s_release(&view);
            PyErr_Format(PyExc_ValueError, "robots: %lld is not one of the %zd robots", r,
                         self->n);
            return NULL;
        }
    }
    F64 *a = self->a;
    for (Py_ssize_t k = 0; k < count; k++) {
        Py_ssize_t i = (Py_ssize_t)INT64_AT(view, k);
        for (int j = 0; j < 7; j++) {
            AT2(a[S_DQ_PREV], i, j) = AT2(a[S_DQ], i, j);
            AT2(a[S_TAU_EXT], i, j) = 0.0;
        }
        model_terms_row(self, i);
    }
    int64s_release(&view);
    Py_RETURN_NONE;
}

static PyObject *Sensing_run(SensingObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "run") < 0) return NULL;
    Py_ssize_t n = self->n, s7[2] = {n, 7};
    Bytes in_motion;
    F64 load;
    memset(&load, 0, sizeof(load));
    if (bytes_get(args[0], &in_motion, n, 0, "in_motion") < 0) return NULL;
    int loaded = args[1] != Py_None;
    if (loaded && f64_get(args[1], &load, 2, s7, 0, "load") < 0) {
        bytes_release(&in_motion);
        return NULL;
    }
    F64 *a = self->a;
    SenseRow r = {&a[S_TAU_EXT], &a[S_TAU_J], &a[S_M_DDQ], &a[S_LOADED], &a[S_JAC], &a[S_ROT],
                  &a[S_DDQ_D], &in_motion, &a[S_LIMITS], self->alpha, self->damping,
                  self->scale, self->phase_bound, &a[S_TAU], &a[S_WRENCH], &a[S_K_WRENCH],
                  &a[S_JOINT_CONTACT], &a[S_CARTESIAN_CONTACT], &a[S_JOINT_OVER],
                  &a[S_CARTESIAN_OVER], &self->accelerating};
    long over = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        /* the step that ended: its acceleration against the M and bias it started from */
        double ddq[7];
        for (int j = 0; j < 7; j++) {
            double dq = AT2(a[S_DQ], i, j);
            ddq[j] = (dq - AT2(a[S_DQ_PREV], i, j)) / self->cycle;
            AT2(a[S_DQ_PREV], i, j) = dq;
        }
        for (int row = 0; row < 7; row++) {
            double sum = 0.0;
            for (int j = 0; j < 7; j++) sum += AT3(a[S_MASS], i, row, j) * ddq[j];
            AT2(a[S_M_DDQ], i, row) = sum;
            double bias = AT2(a[S_BIAS], i, row);
            AT2(a[S_LOADED], i, row) = loaded ? bias + AT2(load, i, row) : bias;
        }
        model_terms_row(self, i); /* the new state's, kept for the next cycle */
        k_frame_row(&a[S_O_T_EE], &a[S_EE_T_K], i, &a[S_POINT], &a[S_ROT]);
        jacobian_row(&a[S_AXES], &a[S_ANCHORS], &a[S_POINT], i, &a[S_JAC]);
        over += sense_row(&r, i);
    }
    bytes_release(&in_motion);
    f64_release(&load);
    return PyLong_FromLong(over);
}

static PyMethodDef SENSING_METHODS[] = {
    {"run", (PyCFunction)(void (*)(void))Sensing_run, METH_FASTCALL,
     "run(in_motion, load) -> the robots over an upper threshold: the cycle's sensing."},
    {"reset", (PyCFunction)Sensing_reset, METH_O,
     "reset(robots): their estimate restarts from zero at the state their arms are at."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject SensingType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.fci.contact._contact.Sensing",
    .tp_basicsize = sizeof(SensingObject),
    .tp_dealloc = (destructor)Sensing_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Sensing(...): a cycle's model terms, estimate, wrench at K and collision "
              "levels, planned; run(in_motion, load).",
    .tp_methods = SENSING_METHODS,
    .tp_new = Sensing_new,
};

static PyMethodDef METHODS[] = {
    METHOD(filter_residual, "One step of the estimate's filter, out given."),
    METHOD(wrench_from_torque, "The wrench at the Jacobian's point, out given."),
    METHOD(in_frame, "A wrench in a frame's axes, out given."),
    METHOD(k_frame, "The frame K from O_T_EE and EE_T_K."),
    METHOD(sense, "A cycle's estimate, wrench at K, contact and collision levels."),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef _contact_definition = {
    PyModuleDef_HEAD_INIT, "_contact",
    "The contact estimate's and the collision levels' rules: their only text (fci/).", -1,
    METHODS, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__contact(void)
{
    if (PyType_Ready(&SensingType) < 0) return NULL;
    PyObject *m = kernel_module(&_contact_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "Sensing", (PyObject *)&SensingType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
