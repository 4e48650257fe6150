/* C replacements of the joint rules' per-joint arithmetic (fci/limits/joint.py and
 * fci/limits/safety.py), chosen by the backend switch (native.load, joint.py KERNEL):
 *
 *   position_rows(q_c, q_prev, dq_prev, ddq_prev, q_start, h, constants, positional,
 *                 start_tolerance, shift, rows, dq, ddq)
 *   velocity_rows(dq_c, q_prev, dq_prev, ddq_prev, dq_start, h, constants, positional,
 *                 start_tolerance, shift, rows, ddq)
 *   measured_velocity_rows(dq, q, constants, positional, shift, margin, outside)
 *
 * Each computes what the numpy rule computes before its precedence table: the backward
 * differences over h, the velocity envelope at the reference (RobotTable.velocity_envelope,
 * fci/tables.py) and, per robot, which rows of the table trip on any joint, as the bits
 * of ``rows`` (bit k: row k of joint.py's _POSITION / _VELOCITY). The table itself (which
 * row wins, its error, the gating by the opening command) stays in numpy: joint.py looks
 * the bits up in the same table as the numpy path. Every constant is an argument:
 * ``constants`` is joint.py's joint_constants(table), the rows q_lower, q_upper, ddq_max,
 * dddq_max, 2 ddq_decel, dq_offset, dq_max of fci/tables.py; ``positional`` 0 for a robot
 * whose envelope is the constant dq_max (the FER); ``shift`` the envelope's tolerance.
 *
 * Elementwise arithmetic in the numpy rule's order, built without fused multiply-adds
 * (setup.py), numpy's NaN-propagating minimum / maximum: the same bits as numpy for
 * every input, non-finite ones included (tests/fci/test_joint_rules_parity.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"

enum { Q_LOWER, Q_UPPER, DDQ_MAX, DDDQ_MAX, TWO_A, OFFSET, VMAX, N_CONSTANTS };

/* numpy's np.maximum / np.minimum of two doubles: a NaN in either is the result. */
static inline double nan_max(double a, double b)
{
    return (a >= b || isnan(a)) ? a : b;
}
static inline double nan_min(double a, double b)
{
    return (a <= b || isnan(a)) ? a : b;
}

/* One half of the envelope in RobotTable.velocity_envelope_halves' order: ``distance``
 * to the stop (q_upper - q, or -q_lower - (-q) for the mirrored lower half). */
static inline double envelope_half(const F64 *c, int j, double distance, int positional,
                                   double shift)
{
    if (!positional) return AT2(*c, VMAX, j) - shift;
    double r = distance * AT2(*c, TWO_A, j);
    r = sqrt(nan_max(r, 0.0));
    r = nan_max(r, AT2(*c, OFFSET, j));
    r -= AT2(*c, OFFSET, j);
    r = nan_min(r, AT2(*c, VMAX, j));
    return r - shift;
}

/* (upper, lower) of the envelope at q for joint j. */
static inline void envelope(const F64 *c, int j, double q, int positional, double shift,
                            double *upper, double *lower)
{
    *upper = envelope_half(c, j, AT2(*c, Q_UPPER, j) - q * 1.0, positional, shift);
    *lower = -envelope_half(c, j, (-AT2(*c, Q_LOWER, j)) - q * -1.0, positional, shift);
}

/* ---- arguments -------------------------------------------------------------------------- */

/* The differencing interval: one float for every robot, or (n,) per robot. */
typedef struct {
    double scalar;
    F64 array;
    int per_robot;
} Interval;

static int interval_get(PyObject *obj, Interval *h, Py_ssize_t n)
{
    memset(h, 0, sizeof(*h));
    if (PyFloat_Check(obj)) {
        h->scalar = PyFloat_AsDouble(obj);
        return 0;
    }
    Py_ssize_t shape[1] = {n};
    h->per_robot = 1;
    return f64_get(obj, &h->array, 1, shape, 0, "h");
}

static inline double interval_at(const Interval *h, Py_ssize_t i)
{
    return h->per_robot ? AT1(h->array, i) : h->scalar;
}

/* A float or int argument (0 on success). */
static int number(PyObject *obj, double *out, const char *name)
{
    *out = PyFloat_AsDouble(obj);
    if (*out == -1.0 && PyErr_Occurred()) {
        PyErr_Format(PyExc_TypeError, "%s: expected a number", name);
        return -1;
    }
    return 0;
}

/* ---- the joint-position and joint-velocity generators -------------------------------- */

/* The two generators' arguments: the command, its history, the start, h, the constants. */
enum { CMD, Q_PREV, DQ_PREV, DDQ_PREV, START, CONSTANTS, ARRAYS };

typedef struct {
    F64 a[ARRAYS];
    F64 out[2];
    Bytes rows;
    Interval h;
    int has_start, positional;
    double tolerance, shift;
    Py_ssize_t n;
} Call;

static void call_release(Call *c)
{
    f64_release_all(c->a, ARRAYS);
    f64_release_all(c->out, 2);
    bytes_release(&c->rows);
    if (c->h.per_robot) f64_release(&c->h.array);
}

/* Borrow the 10 leading arguments and ``outs`` (n, 7) result arrays after them. */
static int call_get(PyObject *const *args, Py_ssize_t nargs, int outs, const char *name,
                    Call *c)
{
    memset(c, 0, sizeof(*c));
    if (check_nargs(nargs, 11 + outs, name) < 0) return -1;
    Py_ssize_t n = c->n = leading(args[0], "command");
    if (n < 0) return -1;
    Py_ssize_t s7[2] = {n, 7}, sc[2] = {N_CONSTANTS, 7};
    static const char *names[] = {"command", "q_prev", "dq_prev", "ddq_prev", "start"};
    for (int k = CMD; k <= DDQ_PREV; k++)
        if (num_get(args[k], &c->a[k], 2, s7, 0, names[k]) < 0) return -1;
    c->has_start = args[START] != Py_None;
    if (c->has_start && num_get(args[START], &c->a[START], 2, s7, 0, "start") < 0) return -1;
    double positional;
    if (interval_get(args[5], &c->h, n) < 0 ||
        f64_get(args[6], &c->a[CONSTANTS], 2, sc, 0, "constants") < 0 ||
        number(args[7], &positional, "positional") < 0 ||
        number(args[8], &c->tolerance, "start_tolerance") < 0 ||
        number(args[9], &c->shift, "shift") < 0 || bytes_get(args[10], &c->rows, n, 1, "rows") < 0)
        return -1;
    c->positional = positional != 0.0;
    for (int k = 0; k < outs; k++)
        if (f64_get(args[11 + k], &c->out[k], 2, s7, 1, "out") < 0) return -1;
    return 0;
}

/* position_rows: bits 12 range, 11 start pose, 14 acceleration, 13 envelope, 15 jerk
 * (joint.py _POSITION's rows 0-4); dq and ddq the implied derivatives. The start row only
 * where q_start is given (numpy: only when a robot opens its motion). */
static PyObject *position_rows(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    Call c;
    PyObject *result = NULL;
    if (call_get(args, nargs, 2, "position_rows", &c) < 0) goto done;
    const F64 *k = &c.a[CONSTANTS];
    for (Py_ssize_t i = 0; i < c.n; i++) {
        const double h = interval_at(&c.h, i);
        unsigned bits = 0;
        for (int j = 0; j < 7; j++) {
            double q_c = num2(&c.a[CMD], i, j), q_prev = num2(&c.a[Q_PREV], i, j);
            double dq = (q_c - q_prev) / h;
            double ddq = (dq - num2(&c.a[DQ_PREV], i, j)) / h;
            double dddq = (ddq - num2(&c.a[DDQ_PREV], i, j)) / h;
            double upper, lower;
            envelope(k, j, q_prev, c.positional, c.shift, &upper, &lower);
            if (!((q_c >= AT2(*k, Q_LOWER, j)) & (q_c <= AT2(*k, Q_UPPER, j)))) bits |= 1u;
            if (c.has_start && fabs(q_c - num2(&c.a[START], i, j)) > c.tolerance) bits |= 2u;
            if (fabs(ddq) > AT2(*k, DDQ_MAX, j)) bits |= 4u;
            if ((dq > upper) | (dq < lower)) bits |= 8u;
            if (fabs(dddq) > AT2(*k, DDDQ_MAX, j)) bits |= 16u;
            AT2(c.out[0], i, j) = dq;
            AT2(c.out[1], i, j) = ddq;
        }
        c.rows.data[i * c.rows.stride] = (char)bits;
    }
    result = Py_NewRef(Py_None);
done:
    call_release(&c);
    return result;
}

/* velocity_rows: bits 13 non-finite, 15 start velocity, 15 acceleration, 15 jerk,
 * 13 envelope (joint.py _VELOCITY's rows 0-4); ddq the implied acceleration. */
static PyObject *velocity_rows(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    Call c;
    PyObject *result = NULL;
    if (call_get(args, nargs, 1, "velocity_rows", &c) < 0) goto done;
    const F64 *k = &c.a[CONSTANTS];
    for (Py_ssize_t i = 0; i < c.n; i++) {
        const double h = interval_at(&c.h, i);
        unsigned bits = 0;
        for (int j = 0; j < 7; j++) {
            double dq_c = num2(&c.a[CMD], i, j);
            double ddq = (dq_c - num2(&c.a[DQ_PREV], i, j)) / h;
            double dddq = (ddq - num2(&c.a[DDQ_PREV], i, j)) / h;
            double upper, lower;
            envelope(k, j, num2(&c.a[Q_PREV], i, j), c.positional, c.shift, &upper, &lower);
            if (!isfinite(dq_c)) bits |= 1u;
            if (c.has_start && fabs(dq_c - num2(&c.a[START], i, j)) > c.tolerance) bits |= 2u;
            if (fabs(ddq) > AT2(*k, DDQ_MAX, j)) bits |= 4u;
            if (fabs(dddq) > AT2(*k, DDDQ_MAX, j)) bits |= 8u;
            if (!((dq_c <= upper) & (dq_c >= lower))) bits |= 16u;
            AT2(c.out[0], i, j) = ddq;
        }
        c.rows.data[i * c.rows.stride] = (char)bits;
    }
    result = Py_NewRef(Py_None);
done:
    call_release(&c);
    return result;
}

/* ---- the safety controller's joint velocity (3) --------------------------------------- */

/* measured_velocity_rows(dq, q, constants, positional, shift, margin, outside): outside[i]
 * is 1 where a joint of robot i leaves the envelope at q widened by ``margin``
 * (safety.py check_measured_joint_velocity: dq <= upper + margin and dq >= lower - margin). */
static PyObject *measured_velocity_rows(PyObject *self, PyObject *const *args,
                                        Py_ssize_t nargs)
{
    (void)self;
    enum { DQ, Q, C };
    F64 a[3];
    Bytes outside;
    memset(a, 0, sizeof(a));
    memset(&outside, 0, sizeof(outside));
    PyObject *result = NULL;
    double positional, shift, margin;
    if (check_nargs(nargs, 7, "measured_velocity_rows") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "dq");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, sc[2] = {N_CONSTANTS, 7};
    if (num_get(args[0], &a[DQ], 2, s7, 0, "dq") < 0 ||
        num_get(args[1], &a[Q], 2, s7, 0, "q") < 0 ||
        f64_get(args[2], &a[C], 2, sc, 0, "constants") < 0 ||
        number(args[3], &positional, "positional") < 0 || number(args[4], &shift, "shift") < 0 ||
        number(args[5], &margin, "margin") < 0 || bytes_get(args[6], &outside, n, 1, "outside") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        unsigned out = 0;
        for (int j = 0; j < 7; j++) {
            double upper, lower, dq = num2(&a[DQ], i, j);
            envelope(&a[C], j, num2(&a[Q], i, j), positional != 0.0, shift, &upper, &lower);
            if (!((dq <= upper + margin) & (dq >= lower - margin))) out = 1u;
        }
        outside.data[i * outside.stride] = (char)out;
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, 3);
    bytes_release(&outside);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(position_rows, "The tripped rows of check_joint_position, and dq, ddq."),
    METHOD(velocity_rows, "The tripped rows of check_joint_velocity, and ddq."),
    METHOD(measured_velocity_rows, "check_measured_joint_velocity's robots outside."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_joint, "C replacements of the joint rules' per-joint arithmetic (fci/limits).")
