/* The robot's joint-side rules of the 1 kHz cycle, each a fused copy of a numpy
 * reference:
 *
 *   envelope(q, constants, shift, out)
 *       fci/tables.py RobotTable.velocity_envelope_halves (the position-based joint
 *       velocity envelope, [upper | -lower]).
 *   positions_inside(q_c, q, dq, ddq, stacked, upper, lower, constants, shift) -> bool
 *       fci/engine.py MotionEngine._positions_inside_limits (q_c's rows 12, 14, 13, 15).
 *   velocities_inside(dq_c, q, dq, ddq, ddq_out, dddq_out, q_out, ddq_max, dddq_max,
 *                     constants, shift) -> bool
 *       fci/engine.py MotionEngine._velocities_inside_limits (dq_c's rows 15 and 13).
 *   measured_inside(dq, q, O_T_EE, ee_prev, measured, bounds) -> bool
 *       the screening comparison of fci/engine.py MotionEngine.safety_controller.
 *
 * Every one is elementwise arithmetic in the reference's order of operations, built
 * without fused multiply-adds (setup.py), so the results are the reference's bits;
 * tests/fci/test_native_joint.py holds each to its reference. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_envelope.h"

#define DELTA_T KERNEL_DT

/* shift: a float, or float64 (14,) or (n, 14) (broadcast against the rows). */
typedef struct {
    double scalar;
    int ndim; /* 0: the scalar */
    F64 array;
} Shift;

static int shift_get(PyObject *obj, Shift *s, Py_ssize_t n)
{
    memset(s, 0, sizeof(*s));
    if (PyFloat_Check(obj) || PyLong_Check(obj)) {
        s->scalar = PyFloat_AsDouble(obj);
        return PyErr_Occurred() ? -1 : 0;
    }
    Py_ssize_t row[1] = {14}, rows[2] = {n, 14};
    if (f64_get(obj, &s->array, 1, row, 0, "shift") == 0) {
        s->ndim = 1;
        return 0;
    }
    PyErr_Clear();
    if (f64_get(obj, &s->array, 2, rows, 0, "shift") == 0) {
        s->ndim = 2;
        return 0;
    }
    PyErr_Clear();
    PyErr_Format(PyExc_ValueError, "shift: expected a float or a float64 (14,) or (%zd, 14) array",
                 n);
    return -1;
}

static inline double shift_at(const Shift *s, Py_ssize_t i, int k)
{
    if (s->ndim == 0) return s->scalar;
    if (s->ndim == 1) return AT1(s->array, k);
    return AT2(s->array, i, k);
}

/* envelope(q, constants, shift, out): out (n, 14) = velocity_envelope_halves(q, shift).
 * q is (n, 7), or (n, 14) already doubled as [q | q] (then out may be q itself). */
static PyObject *envelope(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 4, "envelope") < 0) return NULL;
    F64 a[3];
    Shift s;
    memset(a, 0, sizeof(a));
    memset(&s, 0, sizeof(s));
    Py_ssize_t any2[2] = {-1, -1};
    PyObject *result = NULL;
    if (f64_get(args[0], &a[0], 2, any2, 0, "q") < 0) goto done;
    Py_ssize_t n = a[0].shape[0], width = a[0].shape[1];
    Py_ssize_t out_shape[2] = {n, 14};
    if (width != 7 && width != 14) {
        PyErr_Format(PyExc_ValueError, "q: expected (n, 7) or (n, 14), got width %zd", width);
        goto done;
    }
    if (f64_get(args[1], &a[1], 2, CONSTANTS_SHAPE, 0, "constants") < 0) goto done;
    if (shift_get(args[2], &s, n) < 0) goto done;
    if (f64_get(args[3], &a[2], 2, out_shape, 1, "out") < 0) goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int k = 0; k < 14; k++) {
            double q = AT2(a[0], i, width == 7 ? k % 7 : k);
            AT2(a[2], i, k) = envelope_entry(&a[1], k, q, shift_at(&s, i, k));
        }
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, 3);
    f64_release(&s.array);
    return result;
}

/* positions_inside(q_c, q, dq, ddq, stacked, upper, lower, constants, shift) -> bool
 *
 * stacked (n, 35) receives [q_c | dq | ddq | dddq | q] of q_c against the reference
 * (q, dq, ddq), backward differences over one cycle, divided by DELTA_T as the rule
 * functions divide. True when every row is within [lower, upper] (n, 35): the interior
 * bounds, whose dq block stands in for the envelope; where they cannot decide, the dq
 * block is compared against the exact envelope at the reference's q (shift: the
 * envelope's tolerance) and the q block is not looked at. */
static PyObject *positions_inside(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 9, "positions_inside") < 0) return NULL;
    enum { QC, Q, DQ, DDQ, X, UP, LO, C, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t any7[2] = {-1, 7};
    if (f64_get(args[0], &a[QC], 2, any7, 0, "q_c") < 0) goto done;
    Py_ssize_t n = a[QC].shape[0];
    Py_ssize_t s7[2] = {n, 7}, s35[2] = {n, 35};
    if (f64_get(args[1], &a[Q], 2, s7, 0, "q") < 0) goto done;
    if (f64_get(args[2], &a[DQ], 2, s7, 0, "dq") < 0) goto done;
    if (f64_get(args[3], &a[DDQ], 2, s7, 0, "ddq") < 0) goto done;
    if (f64_get(args[4], &a[X], 2, s35, 1, "stacked") < 0) goto done;
    if (f64_get(args[5], &a[UP], 2, s35, 0, "upper") < 0) goto done;
    if (f64_get(args[6], &a[LO], 2, s35, 0, "lower") < 0) goto done;
    if (f64_get(args[7], &a[C], 2, CONSTANTS_SHAPE, 0, "constants") < 0) goto done;
    double shift = PyFloat_AsDouble(args[8]);
    if (shift == -1.0 && PyErr_Occurred()) goto done;
    int inside = 1;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) {
            double qc = AT2(a[QC], i, j), q = AT2(a[Q], i, j);
            double v = (qc - q) / DELTA_T;
            double acc = (v - AT2(a[DQ], i, j)) / DELTA_T;
            double jerk = (acc - AT2(a[DDQ], i, j)) / DELTA_T;
            double row[5] = {qc, v, acc, jerk, q};
            for (int b = 0; b < 5; b++) {
                AT2(a[X], i, 7 * b + j) = row[b];
                if (row[b] > AT2(a[UP], i, 7 * b + j) || row[b] < AT2(a[LO], i, 7 * b + j))
                    inside = 0;
            }
        }
    }
    if (!inside) {
        /* Undecided (near a stop, or fast): the exact envelope at the reference's q. */
        inside = 1;
        for (Py_ssize_t i = 0; i < n && inside; i++) {
            for (int j = 0; j < 7; j++) {
                double q = AT2(a[Q], i, j);
                double up = envelope_entry(&a[C], j, q, shift);
                double lo = -envelope_entry(&a[C], j + 7, q, shift);
                for (int b = 0; b < 4; b++) {
                    double x = AT2(a[X], i, 7 * b + j);
                    double u = b == 1 ? up : AT2(a[UP], i, 7 * b + j);
                    double l = b == 1 ? lo : AT2(a[LO], i, 7 * b + j);
                    if (x > u || x < l) inside = 0;
                }
            }
        }
    }
    result = PyBool_FromLong(inside);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* velocities_inside(dq_c, q, dq, ddq, ddq_out, dddq_out, q_out, ddq_max, dddq_max,
 *                   constants, shift) -> bool
 *
 * dq_c's implied acceleration and jerk against the reference (q, dq, ddq), backward
 * differences over one cycle divided by DELTA_T as the rule function divides, into
 * ddq_out and dddq_out; q_out = q + dq_c DELTA_T (the reference q_d the command advances
 * to). True when every |ddq| <= ddq_max (7,), every |dddq| <= dddq_max (7,) and dq_c
 * lies within the envelope at q (shift: its tolerance): rows 15 and 13 pass. */
static PyObject *velocities_inside(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 11, "velocities_inside") < 0) return NULL;
    enum { DQC, Q, DQ, DDQ, A_OUT, J_OUT, Q_OUT, A_MAX, J_MAX, C, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t any7[2] = {-1, 7};
    if (f64_get(args[0], &a[DQC], 2, any7, 0, "dq_c") < 0) goto done;
    Py_ssize_t n = a[DQC].shape[0];
    Py_ssize_t s7[2] = {n, 7}, row7[1] = {7};
    if (f64_get(args[1], &a[Q], 2, s7, 0, "q") < 0) goto done;
    if (f64_get(args[2], &a[DQ], 2, s7, 0, "dq") < 0) goto done;
    if (f64_get(args[3], &a[DDQ], 2, s7, 0, "ddq") < 0) goto done;
    if (f64_get(args[4], &a[A_OUT], 2, s7, 1, "ddq_out") < 0) goto done;
    if (f64_get(args[5], &a[J_OUT], 2, s7, 1, "dddq_out") < 0) goto done;
    if (f64_get(args[6], &a[Q_OUT], 2, s7, 1, "q_out") < 0) goto done;
    if (f64_get(args[7], &a[A_MAX], 1, row7, 0, "ddq_max") < 0) goto done;
    if (f64_get(args[8], &a[J_MAX], 1, row7, 0, "dddq_max") < 0) goto done;
    if (f64_get(args[9], &a[C], 2, CONSTANTS_SHAPE, 0, "constants") < 0) goto done;
    double shift = PyFloat_AsDouble(args[10]);
    if (shift == -1.0 && PyErr_Occurred()) goto done;
    int inside = 1;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) {
            double v = AT2(a[DQC], i, j), q = AT2(a[Q], i, j);
            double acc = (v - AT2(a[DQ], i, j)) / DELTA_T;
            double jerk = (acc - AT2(a[DDQ], i, j)) / DELTA_T;
            AT2(a[A_OUT], i, j) = acc;
            AT2(a[J_OUT], i, j) = jerk;
            AT2(a[Q_OUT], i, j) = q + v * DELTA_T;
            if (fabs(acc) > AT1(a[A_MAX], j) || fabs(jerk) > AT1(a[J_MAX], j) ||
                v > envelope_entry(&a[C], j, q, shift) ||
                v < -envelope_entry(&a[C], j + 7, q, shift))
                inside = 0;
        }
    }
    result = PyBool_FromLong(inside);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* measured_inside(dq, q, O_T_EE, ee_prev, measured, bounds) -> bool
 *
 * measured (n, 34) receives [dq | q | v_ee | -dq | -q | -v_ee], v_ee the backward
 * difference of O_T_EE's translation (wire entries 12-14) against ee_prev, times
 * 1 / DELTA_T; True when every entry is <= bounds (34,) (a NaN is not). */
static PyObject *measured_inside(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 6, "measured_inside") < 0) return NULL;
    enum { DQ, Q, T, PREV, X, B, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t any7[2] = {-1, 7};
    if (f64_get(args[0], &a[DQ], 2, any7, 0, "dq") < 0) goto done;
    Py_ssize_t n = a[DQ].shape[0];
    Py_ssize_t s7[2] = {n, 7}, s16[2] = {n, 16}, s3[2] = {n, 3}, s34[2] = {n, 34};
    Py_ssize_t b34[1] = {34};
    if (f64_get(args[1], &a[Q], 2, s7, 0, "q") < 0) goto done;
    if (f64_get(args[2], &a[T], 2, s16, 0, "O_T_EE") < 0) goto done;
    if (f64_get(args[3], &a[PREV], 2, s3, 0, "ee_prev") < 0) goto done;
    if (f64_get(args[4], &a[X], 2, s34, 1, "measured") < 0) goto done;
    if (f64_get(args[5], &a[B], 1, b34, 0, "bounds") < 0) goto done;
    const double rate = 1.0 / DELTA_T; /* the reference multiplies by it */
    int inside = 1;
    for (Py_ssize_t i = 0; i < n; i++) {
        double row[17];
        for (int j = 0; j < 7; j++) {
            row[j] = AT2(a[DQ], i, j);
            row[7 + j] = AT2(a[Q], i, j);
        }
        for (int j = 0; j < 3; j++)
            row[14 + j] = (AT2(a[T], i, 12 + j) - AT2(a[PREV], i, j)) * rate;
        for (int k = 0; k < 17; k++) {
            AT2(a[X], i, k) = row[k];
            AT2(a[X], i, 17 + k) = -row[k];
            if (!(row[k] <= AT1(a[B], k)) || !(-row[k] <= AT1(a[B], 17 + k))) inside = 0;
        }
    }
    result = PyBool_FromLong(inside);
done:
    f64_release_all(a, COUNT);
    return result;
}

static PyMethodDef METHODS[] = {
    {"envelope", (PyCFunction)(void (*)(void))envelope, METH_FASTCALL,
     "envelope(q, constants, shift, out): RobotTable.velocity_envelope_halves into out."},
    {"positions_inside", (PyCFunction)(void (*)(void))positions_inside, METH_FASTCALL,
     "positions_inside(q_c, q, dq, ddq, stacked, upper, lower, constants, shift) -> bool: "
     "MotionEngine._positions_inside_limits."},
    {"velocities_inside", (PyCFunction)(void (*)(void))velocities_inside, METH_FASTCALL,
     "velocities_inside(dq_c, q, dq, ddq, ddq_out, dddq_out, q_out, ddq_max, dddq_max, "
     "constants, shift) -> bool: MotionEngine._velocities_inside_limits."},
    {"measured_inside", (PyCFunction)(void (*)(void))measured_inside, METH_FASTCALL,
     "measured_inside(dq, q, O_T_EE, ee_prev, measured, bounds) -> bool: the safety "
     "controller's screening comparison."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_joint_rules,
              "The robot's joint-side rules of the 1 kHz cycle (fused copies of numpy code).")
