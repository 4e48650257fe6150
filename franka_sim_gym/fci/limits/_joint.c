/* The joint, safety and torque rules' C text (fci/limits/joint.py, safety.py, torque.py):
 *
 *   position_rows(q_c, q_prev, dq_prev, ddq_prev, q_start, h, constants, positional,
 *                 start_tolerance, shift, rows, dq, ddq)
 *   velocity_rows(dq_c, q_prev, dq_prev, ddq_prev, dq_start, h, constants, positional,
 *                 start_tolerance, shift, rows, ddq)
 *   safety_rule(dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt, in_motion)
 *   safety_detail(i, dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt)
 *   torque_rule(tau_c, tau_prev, steps, tau_max, dtau_max, dt)
 *   torque_detail(i, tau_c, tau_prev, steps, tau_max, dtau_max, dt)
 *
 * position_rows and velocity_rows are kernels, chosen by the backend switch (native.load,
 * joint.py KERNEL): they compute what the numpy rule computes before its precedence
 * table: the backward differences over h, the velocity envelope at the reference
 * (RobotTable.velocity_envelope, fci/tables.py) and, per robot, which rows of the table
 * trip on any joint, as the bits of ``rows`` (bit k: row k of joint.py's _POSITION /
 * _VELOCITY). The table itself (which row wins, its error, the gating by the opening
 * command) stays in numpy: joint.py looks the bits up in the same table as the numpy path,
 * and tests/fci/test_joint_rules_parity.py holds them to it bit for bit (non-finite inputs
 * included). safety_rule and safety_detail (the safety controller's errors 3 and 4) and
 * torque_rule and torque_detail (the torque interface's 34 and 32) are their rules whole,
 * their only text (issue 38): no numpy path, no switch (native.require), tested against
 * the documented behaviour (tests/fci/test_safety_rules.py, test_torque_rules.py).
 *
 * Every constant is an argument: ``constants`` is joint.py's joint_constants(table), the
 * rows q_lower, q_upper, ddq_max, dddq_max, 2 ddq_decel, dq_offset, dq_max of
 * fci/tables.py; ``positional`` 0 for a robot whose envelope is the constant dq_max (the
 * FER); ``shift`` the envelope's tolerance. Elementwise arithmetic in the numpy rules'
 * order, built without fused multiply-adds (setup.py), numpy's NaN-propagating minimum /
 * maximum. Inputs are read as float64 (a float32 field is widened first). */
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

/* ---- the safety controller's velocity halves: the rules' only text ------------------- */

/* safety_rule(dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt, in_motion)
 *   -> (error, bad, count)
 *
 * docs/fci-behaviour.md "joint_velocity_violation (3)" and "cartesian_velocity_violation (4)",
 * judged on measured state once a cycle (fci/limits/safety.py check_safety): 3 where a
 * joint's measured dq is not within the envelope at its measured q widened by ``margin``
 * on either side; 4 where the EE's translational speed, the backward difference of its
 * measured position over the cycle ``dt``, is not within ``v_max``; 4 outranks 3 (a cycle
 * that breaks both latches 4 only). "Not within": a NaN reading trips either rule (a
 * physics state gone NaN is not "the arm is within its limits"). ``error`` (n,) int64 3, 4
 * or -1; ``bad`` (n,) bool: an error and ``in_motion`` ((n,) one-byte flags); ``count`` the
 * bad robots. The arrays are made by numpy.empty (the build has no numpy headers). */
enum { E3 = 3, E4 = 4, NO_ERROR = -1 };

static PyObject *np_empty, *np_int64, *np_bool;

/* numpy.empty and its dtypes, looked up on the first call. */
static int numpy_refs(void)
{
    if (np_empty) return 0;
    PyObject *np = PyImport_ImportModule("numpy");
    if (!np) return -1;
    np_int64 = PyObject_GetAttrString(np, "int64");
    np_bool = PyObject_GetAttrString(np, "bool_");
    np_empty = PyObject_GetAttrString(np, "empty");
    Py_DECREF(np);
    if (!np_empty || !np_int64 || !np_bool) {
        Py_CLEAR(np_empty);
        Py_CLEAR(np_int64);
        Py_CLEAR(np_bool);
        return -1;
    }
    return 0;
}

/* numpy.empty((n,), dtype). */
static PyObject *empty1(Py_ssize_t n, PyObject *dtype)
{
    PyObject *shape = Py_BuildValue("(n)", n);
    if (!shape) return NULL;
    PyObject *args[2] = {shape, dtype};
    PyObject *a = PyObject_Vectorcall(np_empty, args, 2, NULL);
    Py_DECREF(shape);
    return a;
}

/* A detail entry point's robot index (args[0], any integer) and, once n is known, its range.
 * 0, or -1 with the exception set. */
static int robot_index(PyObject *obj, Py_ssize_t *i)
{
    *i = PyLong_AsSsize_t(obj);
    return (*i == -1 && PyErr_Occurred()) ? -1 : 0;
}
static int robot_in_range(Py_ssize_t i, Py_ssize_t n, const char *name)
{
    if (i >= 0 && i < n) return 0;
    PyErr_Format(PyExc_IndexError, "%s: robot %zd of %zd", name, i, n);
    return -1;
}

/* The rules' arguments after the robot axis: dq, q, ee, ee_prev, the table, the margin. */
enum { S_DQ, S_Q, S_EE, S_EEP, S_C, S_ARRAYS };

typedef struct {
    F64 a[S_ARRAYS];
    int positional;
    double shift, margin, v_max, dt;
    Py_ssize_t n;
} Safety;

/* Borrow dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt at
 * args[0..9]. */
static int safety_get(PyObject *const *args, Safety *s)
{
    memset(s, 0, sizeof(*s));
    Py_ssize_t n = s->n = leading(args[0], "dq");
    if (n < 0) return -1;
    Py_ssize_t s7[2] = {n, 7}, s3[2] = {n, 3}, sc[2] = {N_CONSTANTS, 7};
    double positional;
    if (num_get(args[0], &s->a[S_DQ], 2, s7, 0, "dq") < 0 ||
        num_get(args[1], &s->a[S_Q], 2, s7, 0, "q") < 0 ||
        num_get(args[2], &s->a[S_EE], 2, s3, 0, "ee") < 0 ||
        num_get(args[3], &s->a[S_EEP], 2, s3, 0, "ee_prev") < 0 ||
        f64_get(args[4], &s->a[S_C], 2, sc, 0, "constants") < 0 ||
        number(args[5], &positional, "positional") < 0 ||
        number(args[6], &s->shift, "shift") < 0 || number(args[7], &s->margin, "margin") < 0 ||
        number(args[8], &s->v_max, "v_max") < 0 || number(args[9], &s->dt, "dt") < 0)
        return -1;
    s->positional = positional != 0.0;
    return 0;
}

/* Robot i's joint j: the envelope at its measured q widened by the margin. */
static inline void widened(const Safety *s, Py_ssize_t i, int j, double *upper, double *lower)
{
    envelope(&s->a[S_C], j, num2(&s->a[S_Q], i, j), s->positional, s->shift, upper, lower);
    *upper += s->margin;
    *lower -= s->margin;
}

/* Robot i's EE speed over the cycle. */
static inline double ee_speed(const Safety *s, Py_ssize_t i)
{
    const double inv = 1.0 / s->dt;
    double sum = 0.0;
    for (int k = 0; k < 3; k++) {
        double v = (num2(&s->a[S_EE], i, k) - num2(&s->a[S_EEP], i, k)) * inv;
        sum += v * v;
    }
    return sqrt(sum);
}

/* Robot i's error: 4, else 3, else -1. */
static inline long long safety_error(const Safety *s, Py_ssize_t i)
{
    if (!(ee_speed(s, i) <= s->v_max)) return E4;
    for (int j = 0; j < 7; j++) {
        double upper, lower, dq = num2(&s->a[S_DQ], i, j);
        widened(s, i, j, &upper, &lower);
        if (!((dq <= upper) & (dq >= lower))) return E3;
    }
    return NO_ERROR;
}

static PyObject *safety_rule(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    Safety s;
    Bytes motion;
    Py_buffer err_view = {0}, bad_view = {0};
    PyObject *error = NULL, *bad = NULL, *result = NULL;
    memset(&s, 0, sizeof(s));
    memset(&motion, 0, sizeof(motion));
    if (check_nargs(nargs, 11, "safety_rule") < 0 || numpy_refs() < 0) return NULL;
    if (safety_get(args, &s) < 0 || bytes_get(args[10], &motion, s.n, 0, "in_motion") < 0)
        goto done;
    error = empty1(s.n, np_int64);
    bad = error ? empty1(s.n, np_bool) : NULL;
    if (!bad || PyObject_GetBuffer(error, &err_view, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0 ||
        PyObject_GetBuffer(bad, &bad_view, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0)
        goto done;
    long long *err_out = err_view.buf;
    char *bad_out = bad_view.buf;
    Py_ssize_t count = 0;
    for (Py_ssize_t i = 0; i < s.n; i++) {
        long long e = safety_error(&s, i);
        int b = e != NO_ERROR && BYTE1(motion, i);
        err_out[i] = e;
        bad_out[i] = (char)b;
        count += b;
    }
    result = Py_BuildValue("(OOn)", error, bad, count);
done:
    if (err_view.obj) PyBuffer_Release(&err_view);
    if (bad_view.obj) PyBuffer_Release(&bad_view);
    Py_XDECREF(error);
    Py_XDECREF(bad);
    f64_release_all(s.a, S_ARRAYS);
    bytes_release(&motion);
    return result;
}

/* safety_detail(i, dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt)
 *   -> None | (error, joint, value, upper, lower)
 *
 * What robot i's error was about, for the log line (safety.py describe_safety): for 4 the
 * EE speed (joint -1, bounds v_max and -inf); for 3 the first joint whose dq is not finite
 * (bounds NaN), else the joint furthest outside its widened envelope (the first of equals)
 * and that envelope (a NaN excess, from a NaN q, counting as the largest, as numpy's
 * argmax). The same helpers as safety_rule: one text of the rule. */
static PyObject *safety_detail(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    Safety s;
    PyObject *result = NULL;
    memset(&s, 0, sizeof(s));
    if (check_nargs(nargs, 11, "safety_detail") < 0) return NULL;
    Py_ssize_t i;
    if (robot_index(args[0], &i) < 0) return NULL;
    if (safety_get(args + 1, &s) < 0 || robot_in_range(i, s.n, "safety_detail") < 0) goto done;
    long long e = safety_error(&s, i);
    if (e == E4) {
        result = Py_BuildValue("(Lidd d)", e, -1, ee_speed(&s, i), s.v_max, -INFINITY);
        goto done;
    }
    if (e == NO_ERROR) {
        result = Py_NewRef(Py_None);
        goto done;
    }
    int worst = -1;
    double excess = -INFINITY, upper_w = NAN, lower_w = NAN;
    for (int j = 0; j < 7; j++) {
        double upper, lower, dq = num2(&s.a[S_DQ], i, j);
        widened(&s, i, j, &upper, &lower);
        if (!isfinite(dq)) {
            result = Py_BuildValue("(Lidd d)", e, j, dq, NAN, NAN);
            goto done;
        }
        if ((dq <= upper) & (dq >= lower)) continue;
        /* numpy's argmax of np.maximum(dq - upper, lower - dq): a NaN (an envelope at a NaN
         * q) is the largest, the first of equals wins */
        double x = nan_max(dq - upper, lower - dq);
        if (worst < 0 || (isnan(x) && !isnan(excess)) || x > excess)
            worst = j, excess = x, upper_w = upper, lower_w = lower;
    }
    if (worst < 0) { /* safety_error found a joint outside: this loop must too */
        PyErr_SetString(PyExc_SystemError, "safety_detail: error 3 without a joint outside");
        goto done;
    }
    result = Py_BuildValue("(Lidd d)", e, worst, num2(&s.a[S_DQ], i, worst), upper_w, lower_w);
done:
    f64_release_all(s.a, S_ARRAYS);
    return result;
}


/* ---- the torque interface's rows 34 and 32: the rules' only text ---------------------- */

/* torque_rule(tau_c, tau_prev, steps, tau_max, dtau_max, dt) -> error
 *
 * docs/fci-behaviour.md "What is checked, and what it latches", the torque rows in
 * precedence order (fci/limits/torque.py check_torque): 34 where a joint's commanded torque
 * is not within |tau| <= tau_max[j] (the URDF's effort limit; "not within": NaN lands on
 * 34), else 32 where a joint's rate (tau_c - tau_prev) / (steps dt) is above dtau_max
 * (kMaxTorqueRate = 1000 - 1e-3 Nm/s). ``steps``: one integer for every robot, or a 0-d
 * or (n,) integer array (the published cycles since tau_prev was applied). ``error`` (n,)
 * int64 34, 32 or -1, made by numpy.empty. */
enum { E32 = 32, E34 = 34 };

/* A per-robot integer: one value for every robot, or a 0-d / (n,) integer buffer. */
typedef struct {
    Py_buffer view;
    int per_robot;
    int is_unsigned;
    long long scalar;
} Steps;

static void steps_release(Steps *p)
{
    if (p->view.obj) PyBuffer_Release(&p->view);
    p->view.obj = NULL;
}

static int steps_get(PyObject *obj, Steps *p, Py_ssize_t n)
{
    memset(p, 0, sizeof(*p));
    if (!PyObject_CheckBuffer(obj)) {
        p->scalar = PyLong_AsLongLong(obj);
        if (p->scalar == -1 && PyErr_Occurred()) {
            PyErr_SetString(PyExc_TypeError, "steps: expected an integer or an integer array");
            return -1;
        }
        return 0;
    }
    if (PyObject_GetBuffer(obj, &p->view, PyBUF_RECORDS_RO) < 0) return -1;
    const char *f = p->view.format;
    if (f && (*f == '<' || *f == '=' || *f == '@' || *f == '|')) f++;
    char c = f ? *f : 0;
    int is_signed = c == 'b' || c == 'h' || c == 'i' || c == 'l' || c == 'q';
    p->is_unsigned = c == 'B' || c == 'H' || c == 'I' || c == 'L' || c == 'Q';
    Py_ssize_t size = p->view.itemsize;
    if ((!is_signed && !p->is_unsigned) || f[1] != 0 || p->view.ndim > 1 ||
        (size != 1 && size != 2 && size != 4 && size != 8) ||
        (p->view.ndim == 1 && p->view.shape[0] != n)) {
        PyErr_Format(PyExc_ValueError, "steps: expected one integer or (%zd,) integers", n);
        steps_release(p);
        return -1;
    }
    p->per_robot = p->view.ndim == 1;
    return 0;
}

/* Robot i's steps as a double, as numpy's float64 conversion gives it (the 0-d array's
 * one value for every robot). */
static inline double steps_at(const Steps *p, Py_ssize_t i)
{
    if (!p->view.obj) return (double)p->scalar;
    const char *q = (const char *)p->view.buf + (p->per_robot ? i * p->view.strides[0] : 0);
    switch (p->view.itemsize) {
    case 1: return p->is_unsigned ? *(const unsigned char *)q : *(const signed char *)q;
    case 2: {
        unsigned short u;
        memcpy(&u, q, 2);
        return p->is_unsigned ? (double)u : (double)(short)u;
    }
    case 4: {
        unsigned int u;
        memcpy(&u, q, 4);
        return p->is_unsigned ? (double)u : (double)(int)u;
    }
    default: {
        unsigned long long u;
        memcpy(&u, q, 8);
        return p->is_unsigned ? (double)u : (double)(long long)u;
    }
    }
}

/* The rules' arguments: tau_c, tau_prev, steps, tau_max, dtau_max, dt from args[0]. */
enum { T_TAU, T_PREV, T_MAX, T_ARRAYS };

typedef struct {
    F64 a[T_ARRAYS];
    Steps steps;
    double dtau_max, dt;
    Py_ssize_t n;
} Torque;

static void torque_release(Torque *t)
{
    f64_release_all(t->a, T_ARRAYS);
    steps_release(&t->steps);
}

static int torque_get(PyObject *const *args, Torque *t)
{
    memset(t, 0, sizeof(*t));
    Py_ssize_t n = t->n = leading(args[0], "tau_c");
    if (n < 0) return -1;
    Py_ssize_t s7[2] = {n, 7}, s1[1] = {7};
    if (num_get(args[0], &t->a[T_TAU], 2, s7, 0, "tau_c") < 0 ||
        num_get(args[1], &t->a[T_PREV], 2, s7, 0, "tau_prev") < 0 ||
        steps_get(args[2], &t->steps, n) < 0 ||
        f64_get(args[3], &t->a[T_MAX], 1, s1, 0, "tau_max") < 0 ||
        number(args[4], &t->dtau_max, "dtau_max") < 0 || number(args[5], &t->dt, "dt") < 0)
        return -1;
    return 0;
}

/* Robot i's joint j: its torque and its rate over the robot's interval. */
static inline double torque_at(const Torque *t, Py_ssize_t i, int j)
{
    return num2(&t->a[T_TAU], i, j);
}
static inline double rate_at(const Torque *t, Py_ssize_t i, int j)
{
    const double h = steps_at(&t->steps, i) * t->dt;
    return (num2(&t->a[T_TAU], i, j) - num2(&t->a[T_PREV], i, j)) / h;
}
static inline int outside_range(const Torque *t, Py_ssize_t i, int j)
{
    return !(fabs(torque_at(t, i, j)) <= AT1(t->a[T_MAX], j));
}
static inline int over_rate(const Torque *t, Py_ssize_t i, int j)
{
    return fabs(rate_at(t, i, j)) > t->dtau_max;
}

/* Robot i's error: 34 on any joint, else 32 on any joint, else -1. */
static inline long long torque_error(const Torque *t, Py_ssize_t i)
{
    for (int j = 0; j < 7; j++)
        if (outside_range(t, i, j)) return E34;
    for (int j = 0; j < 7; j++)
        if (over_rate(t, i, j)) return E32;
    return NO_ERROR;
}

static PyObject *torque_rule(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    Torque t;
    Py_buffer view = {0};
    PyObject *error = NULL, *result = NULL;
    memset(&t, 0, sizeof(t));
    if (check_nargs(nargs, 6, "torque_rule") < 0 || numpy_refs() < 0) return NULL;
    if (torque_get(args, &t) < 0) goto done;
    error = empty1(t.n, np_int64);
    if (!error || PyObject_GetBuffer(error, &view, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0)
        goto done;
    long long *out = view.buf;
    for (Py_ssize_t i = 0; i < t.n; i++) out[i] = torque_error(&t, i);
    result = Py_NewRef(error);
done:
    if (view.obj) PyBuffer_Release(&view);
    Py_XDECREF(error);
    torque_release(&t);
    return result;
}

/* torque_detail(i, tau_c, tau_prev, steps, tau_max, dtau_max, dt)
 *   -> None | (error, joint, value, limit)
 *
 * What robot i's error was about, for the log line (torque.py describe_torque): the row
 * that won (34: the torque, limit tau_max[j]; 32: the rate, limit dtau_max; both limits
 * the magnitude of a symmetric bound), and in it the first joint whose value is not finite
 * (limit NaN), else the joint furthest beyond the bound (the first of equals). */
static PyObject *torque_detail(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    Torque t;
    PyObject *result = NULL;
    memset(&t, 0, sizeof(t));
    if (check_nargs(nargs, 7, "torque_detail") < 0) return NULL;
    Py_ssize_t i;
    if (robot_index(args[0], &i) < 0) return NULL;
    if (torque_get(args + 1, &t) < 0 || robot_in_range(i, t.n, "torque_detail") < 0) goto done;
    long long e = torque_error(&t, i);
    if (e == NO_ERROR) {
        result = Py_NewRef(Py_None);
        goto done;
    }
    int worst = -1;
    double excess = -INFINITY, value_w = NAN, limit_w = NAN;
    for (int j = 0; j < 7; j++) {
        int tripped = e == E34 ? outside_range(&t, i, j) : over_rate(&t, i, j);
        if (!tripped) continue;
        double value = e == E34 ? torque_at(&t, i, j) : rate_at(&t, i, j);
        double limit = e == E34 ? AT1(t.a[T_MAX], j) : t.dtau_max;
        if (!isfinite(value)) {
            result = Py_BuildValue("(Lidd)", e, j, value, NAN);
            goto done;
        }
        double x = fabs(value) - limit; /* max(value - limit, -limit - value) */
        if (worst < 0 || x > excess) worst = j, excess = x, value_w = value, limit_w = limit;
    }
    if (worst < 0) { /* torque_error found a joint beyond: this loop must too */
        PyErr_SetString(PyExc_SystemError, "torque_detail: an error without a joint beyond");
        goto done;
    }
    result = Py_BuildValue("(Lidd)", e, worst, value_w, limit_w);
done:
    torque_release(&t);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(position_rows, "The tripped rows of check_joint_position, and dq, ddq."),
    METHOD(velocity_rows, "The tripped rows of check_joint_velocity, and ddq."),
    METHOD(safety_rule, "Errors 3 and 4 of every robot, 4 over 3: (error, bad, count)."),
    METHOD(torque_rule, "Errors 34 and 32 of every robot, 34 over 32: error."),
    METHOD(torque_detail, "Robot i's error 34 or 32 for the log line: (error, joint, value, limit)."),
    METHOD(safety_detail, "Robot i's error 3 or 4 for the log line: (error, joint, value, upper, lower)."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_joint, "The joint rules' per-joint arithmetic, and the safety and torque rules whole (fci/limits).")
