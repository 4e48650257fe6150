/* The joint and Cartesian generators', the safety controller's and the torque interface's rules,
 * and the joint generators' cycle (the lost-cycle laws, the reference's record): their only
 * text (issue 38: one text per rule, compiled; fci/limits/joint.py, cartesian.py, safety.py,
 * torque.py, fci/joint_generators.py and fci/extrapolation.py hand them the table's
 * constants and name what they find):
 *
 *   envelope_halves(q, constants, positional, shift, out)
 *   position_rule(q_c, q_prev, dq_prev, ddq_prev, first, q_start, steps, constants,
 *                 positional, start_tolerance, shift, dt) -> (error, dq, ddq)
 *   velocity_rule(dq_c, <the same>) -> (error, ddq)
 *   position_detail(i, <position_rule's>), velocity_detail(i, <velocity_rule's>)
 *   safety_rule(dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt, in_motion)
 *   safety_detail(i, dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt)
 *   torque_rule(tau_c, tau_prev, steps, tau_max, dtau_max, dt)
 *   torque_detail(i, tau_c, tau_prev, steps, tau_max, dtau_max, dt)
 *   cartesian_rule(kind, codes, stacked, first, start_pose, start_elbow, elbow, ...) (below)
 *   JointCycle(aborted, ..., new_ddq).advance(q_c, dq_c, have, ...) -> pending (below)
 *   joint_record(rows, have, new_q, new_dq, new_ddq, echo, <the reference>) (below)
 *   position_step(x, v, a, dt) -> (x', v'), velocity_step(v, a, dt) -> v'
 *
 * A rule returns every robot's latched error; its detail what robot i's error was about, for
 * the log line, computed by the same helpers. No numpy path, no switch (native.require): the
 * tests hold each to the documented behaviour (tests/fci/test_joint_rules*.py,
 * test_safety_rules.py, test_torque_rules.py).
 *
 * Every constant is an argument: ``constants`` is RobotTable.joint_constants, the
 * rows q_lower, q_upper, ddq_max, dddq_max, 2 ddq_decel, dq_offset, dq_max of
 * fci/tables.py; ``positional`` 0 for a robot whose envelope is the constant dq_max (the
 * FER); ``shift`` the envelope's tolerance; ``dt`` the cycle (fci/tables.py DELTA_T).
 * Elementwise arithmetic in the order numpy's texts had it (the published states did not
 * move), built without fused multiply-adds (setup.py), numpy's NaN-propagating minimum /
 * maximum. Inputs are read as float64 (a float32 field is widened first). The error codes
 * are fci/errors.py's Error indices (libfranka's robot_state.h order). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"

#include "_envelope.h"

/* ---- arguments and results ------------------------------------------------------------ */

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

/* A per-robot integer or flag: one value for every robot (a Python int or bool), or a 0-d /
 * (n,) integer or bool buffer. */
typedef struct {
    Py_buffer view;
    int per_robot;
    int is_unsigned;
    long long scalar;
} PerRobot;

static void per_robot_release(PerRobot *p)
{
    if (p->view.obj) PyBuffer_Release(&p->view);
    p->view.obj = NULL;
}

static int per_robot_get(PyObject *obj, PerRobot *p, Py_ssize_t n, const char *name)
{
    memset(p, 0, sizeof(*p));
    if (!PyObject_CheckBuffer(obj)) {
        p->scalar = PyLong_AsLongLong(obj);
        if (p->scalar == -1 && PyErr_Occurred()) {
            PyErr_Format(PyExc_TypeError, "%s: expected an integer or an integer array", name);
            return -1;
        }
        return 0;
    }
    if (PyObject_GetBuffer(obj, &p->view, PyBUF_RECORDS_RO) < 0) return -1;
    const char *f = p->view.format;
    if (f && (*f == '<' || *f == '=' || *f == '@' || *f == '|')) f++;
    char c = f ? *f : 0;
    int is_signed = c == 'b' || c == 'h' || c == 'i' || c == 'l' || c == 'q';
    p->is_unsigned = c == 'B' || c == 'H' || c == 'I' || c == 'L' || c == 'Q' || c == '?';
    Py_ssize_t size = p->view.itemsize;
    if ((!is_signed && !p->is_unsigned) || f[1] != 0 || p->view.ndim > 1 ||
        (size != 1 && size != 2 && size != 4 && size != 8) ||
        (p->view.ndim == 1 && p->view.shape[0] != n)) {
        PyErr_Format(PyExc_ValueError, "%s: expected one integer or (%zd,) integers", name, n);
        per_robot_release(p);
        return -1;
    }
    p->per_robot = p->view.ndim == 1;
    return 0;
}

/* Robot i's value as a double, as numpy's float64 conversion gives it (the 0-d array's
 * one value for every robot). */
static inline double per_robot_at(const PerRobot *p, Py_ssize_t i)
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

/* The "no violation" value of every error array (fci/limits/record.py NO_ERROR). */
enum { NO_ERROR = -1 };

static PyObject *np_empty, *np_int64, *np_bool, *np_float64;

/* numpy.empty and its dtypes, looked up on the first call. */
static int numpy_refs(void)
{
    if (np_empty) return 0;
    PyObject *np = PyImport_ImportModule("numpy");
    if (!np) return -1;
    np_int64 = PyObject_GetAttrString(np, "int64");
    np_bool = PyObject_GetAttrString(np, "bool_");
    np_float64 = PyObject_GetAttrString(np, "float64");
    np_empty = PyObject_GetAttrString(np, "empty");
    Py_DECREF(np);
    if (!np_empty || !np_int64 || !np_bool || !np_float64) {
        Py_CLEAR(np_empty);
        Py_CLEAR(np_int64);
        Py_CLEAR(np_bool);
        Py_CLEAR(np_float64);
        return -1;
    }
    return 0;
}

/* numpy.empty((n,), dtype), or (n, cols) where cols > 0. */
static PyObject *empty(Py_ssize_t n, Py_ssize_t cols, PyObject *dtype)
{
    PyObject *shape = cols > 0 ? Py_BuildValue("(nn)", n, cols) : Py_BuildValue("(n)", n);
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

/* ---- the velocity envelope's law, for every caller ------------------------------------- */

/* envelope_halves(q, constants, positional, shift, out)
 *
 * fci/tables.py RobotTable.velocity_envelope_halves, the law's only text (libfranka >= 0.18
 * src/joint_velocity_limits.cpp, docs/limits.md §4): for each row of q (m, 7), out (m, 14)
 * = [upper | -lower] of the envelope at q with ``shift`` in place of the tolerance (one
 * number, or (m, 14) per bound: the caller's margins). ``out`` may be q's own storage (a
 * doubled [q | q]): each joint's q is read before its two bounds are written. */
static PyObject *envelope_halves(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    F64 q, c, shift, out;
    PyObject *result = NULL;
    memset(&q, 0, sizeof(q)), memset(&c, 0, sizeof(c));
    memset(&shift, 0, sizeof(shift)), memset(&out, 0, sizeof(out));
    if (check_nargs(nargs, 5, "envelope_halves") < 0) return NULL;
    Py_ssize_t m = leading(args[0], "q");
    if (m < 0) return NULL;
    Py_ssize_t s7[2] = {m, 7}, s14[2] = {m, 14}, sc[2] = {N_CONSTANTS, 7};
    double positional, shift_all = 0.0;
    const int per_bound = PyObject_CheckBuffer(args[3]);
    if (num_get(args[0], &q, 2, s7, 0, "q") < 0 ||
        f64_get(args[1], &c, 2, sc, 0, "constants") < 0 ||
        number(args[2], &positional, "positional") < 0 ||
        (per_bound ? f64_get(args[3], &shift, 2, s14, 0, "shift")
                   : number(args[3], &shift_all, "shift")) < 0 ||
        f64_get(args[4], &out, 2, s14, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < m; i++)
        for (int j = 0; j < 7; j++) {
            const double qj = num2(&q, i, j);
            const double up = per_bound ? AT2(shift, i, j) : shift_all;
            const double down = per_bound ? AT2(shift, i, j + 7) : shift_all;
            const int pos = positional != 0.0;
            /* envelope()'s two halves, each with its own shift */
            const double upper = envelope_half(&c, j, AT2(c, Q_UPPER, j) - qj * 1.0, pos, up);
            const double minus_lower =
                envelope_half(&c, j, (-AT2(c, Q_LOWER, j)) - qj * -1.0, pos, down);
            AT2(out, i, j) = upper;
            AT2(out, i, j + 7) = minus_lower;
        }
    result = Py_NewRef(Py_None);
done:
    f64_release(&q), f64_release(&c), f64_release(&shift), f64_release(&out);
    return result;
}

/* ---- the joint-position and joint-velocity generators: the rules' only text ----------- */

/* position_rule(q_c, q_prev, dq_prev, ddq_prev, first, q_start, steps, constants, positional,
 *               start_tolerance, shift, dt) -> (error, dq, ddq)
 * velocity_rule(dq_c, <the same>) -> (error, ddq)
 * position_detail(i, <position_rule's arguments>) -> None | (error, row, joint, value, limit)
 * velocity_detail(i, <velocity_rule's arguments>) -> None | (error, row, joint, value, limit)
 *
 * docs/fci-behaviour.md "What is checked, and what it latches": each generator's rows in
 * precedence order, the first row that trips on any joint latching its error (one per robot;
 * fci/limits/joint.py check_joint_position / check_joint_velocity, which name the rows).
 *
 *   q_c:  0 range (12; "not inside", so NaN lands here: docs/fci-behaviour.md, a non-finite
 *         command is the limits violation of the generator it arrived in), 1 start pose (11),
 *         2 acceleration (14), 3 the envelope at q_d (13), 4 jerk (15).
 *   dq_c: 0 non-finite (13, ours, first: inf would read as a 15 step, NaN passes every `>`),
 *         1 start velocity (15), 2 acceleration (15), 3 jerk (15), 4 the envelope at q_d (13).
 *
 * Rows 1 apply only to a motion's opening command (``first``: the robot at rest, so the
 * start check is the check); the derivative rows only after it; the dq_c envelope always.
 * The derivatives are backward differences over h = steps dt (docs/fci-behaviour.md "The
 * difference formulas": steps the published cycles since the command the history sits
 * at): dq = (q_c - q_prev) / h, ddq = (dq - dq_prev) / h, dddq = (ddq - ddq_prev) / h.
 * ``error`` (n,) int64 the latched Error index or -1; dq / ddq (n, 7) the implied
 * derivatives to record, zero where ``first`` (the history rebased at rest), meaningless
 * for a robot whose error is 12. A detail is robot i's winning row, and in it the first
 * joint whose value is not finite (limit NaN), else the joint furthest outside (the first
 * of equals; a NaN excess, from a NaN envelope, the largest) and the bound it crossed
 * (the upper one for the symmetric rows 1-3 of dq_c, 1, 2, 4 of q_c). */
enum { ROWS = 5 };

/* Each row's error (fci/errors.py, libfranka robot_state.h's order): 11
 * joint_position_motion_generator_start_pose_invalid, 12
 * joint_motion_generator_position_limits_violation, 13 ..._velocity_limits_violation, 14
 * ..._velocity_discontinuity, 15 ..._acceleration_discontinuity. */
static const long long POSITION_CODES[ROWS] = {12, 11, 14, 13, 15};
static const long long VELOCITY_CODES[ROWS] = {13, 15, 15, 15, 13};
/* The rows that apply, bit k row k: [after the opening command, on it]. q_c: the start row
 * only on it, the derivative rows 2-4 only after. dq_c: the start row only on it, the
 * acceleration and jerk only after, the envelope always. */
static const unsigned POSITION_GATE[2] = {0x1Du, 0x03u};
static const unsigned VELOCITY_GATE[2] = {0x1Du, 0x13u};
/* The rows whose bound is |x| <= b: the log line gives b for either side. */
static const unsigned POSITION_SYMMETRIC = 0x16u, VELOCITY_SYMMETRIC = 0x0Eu;

/* The command, its history, the start, the constants. */
enum { CMD, Q_PREV, DQ_PREV, DDQ_PREV, START, CONSTANTS, ARRAYS };

typedef struct {
    F64 a[ARRAYS];
    PerRobot first, steps;
    int positional;
    double tolerance, shift, dt;
    Py_ssize_t n;
} Joint;

static void joint_release(Joint *r)
{
    f64_release_all(r->a, ARRAYS);
    per_robot_release(&r->first);
    per_robot_release(&r->steps);
}

/* Borrow the rules' 12 arguments from args[0]. */
static int joint_get(PyObject *const *args, Joint *r)
{
    memset(r, 0, sizeof(*r));
    Py_ssize_t n = r->n = leading(args[0], "command");
    if (n < 0) return -1;
    Py_ssize_t s7[2] = {n, 7}, sc[2] = {N_CONSTANTS, 7};
    static const char *names[] = {"command", "q_prev", "dq_prev", "ddq_prev"};
    for (int k = CMD; k <= DDQ_PREV; k++)
        if (num_get(args[k], &r->a[k], 2, s7, 0, names[k]) < 0) return -1;
    double positional;
    if (per_robot_get(args[4], &r->first, n, "first") < 0 ||
        num_get(args[5], &r->a[START], 2, s7, 0, "start") < 0 ||
        per_robot_get(args[6], &r->steps, n, "steps") < 0 ||
        f64_get(args[7], &r->a[CONSTANTS], 2, sc, 0, "constants") < 0 ||
        number(args[8], &positional, "positional") < 0 ||
        number(args[9], &r->tolerance, "start_tolerance") < 0 ||
        number(args[10], &r->shift, "shift") < 0 || number(args[11], &r->dt, "dt") < 0)
        return -1;
    r->positional = positional != 0.0;
    return 0;
}

/* Robot i's joint j under one rule: each row's checked value and bounds. */
typedef struct {
    double value[ROWS], upper[ROWS], lower[ROWS];
} Terms;

/* Row k's checked value and bounds into ``t`` (the detail's; the rule passes NULL). */
static inline void term(Terms *t, int k, double value, double upper, double lower)
{
    if (t) t->value[k] = value, t->upper[k] = upper, t->lower[k] = lower;
}

/* q_c's rows on robot i's joint j: the bits that trip, and the terms behind them into
 * ``t`` unless NULL; dq and ddq into ``d``. */
static ALWAYS_INLINE unsigned position_joint(
    const Joint *r, Py_ssize_t i, int j, int first, double h, Terms *t, double d[2])
{
    const F64 *k = &r->a[CONSTANTS];
    const double q_lower = AT2(*k, Q_LOWER, j), q_upper = AT2(*k, Q_UPPER, j);
    const double ddq_max = AT2(*k, DDQ_MAX, j), dddq_max = AT2(*k, DDDQ_MAX, j);
    double q_c = num2(&r->a[CMD], i, j), q_prev = num2(&r->a[Q_PREV], i, j);
    double dq = (q_c - q_prev) / h;
    double ddq = (dq - num2(&r->a[DQ_PREV], i, j)) / h;
    double dddq = (ddq - num2(&r->a[DDQ_PREV], i, j)) / h;
    double start = first ? q_c - num2(&r->a[START], i, j) : 0.0;
    double upper, lower;
    /* docs/limits.md §4: the envelope is evaluated at the reference (q_d), never at q */
    envelope(k, j, q_prev, r->positional, r->shift, &upper, &lower);
    term(t, 0, q_c, q_upper, q_lower);
    term(t, 1, start, r->tolerance, -r->tolerance);
    term(t, 2, ddq, ddq_max, -ddq_max);
    term(t, 3, dq, upper, lower);
    term(t, 4, dddq, dddq_max, -dddq_max);
    d[0] = dq, d[1] = ddq;
    unsigned bits = 0;
    if (!((q_c >= q_lower) & (q_c <= q_upper))) bits |= 1u;
    if (first && fabs(start) > r->tolerance) bits |= 2u;
    if (fabs(ddq) > ddq_max) bits |= 4u;
    if ((dq > upper) | (dq < lower)) bits |= 8u;
    if (fabs(dddq) > dddq_max) bits |= 16u;
    return bits;
}

/* dq_c's rows on robot i's joint j; ddq into ``d``. */
static ALWAYS_INLINE unsigned velocity_joint(
    const Joint *r, Py_ssize_t i, int j, int first, double h, Terms *t, double d[2])
{
    const F64 *k = &r->a[CONSTANTS];
    const double ddq_max = AT2(*k, DDQ_MAX, j), dddq_max = AT2(*k, DDDQ_MAX, j);
    double dq_c = num2(&r->a[CMD], i, j);
    double ddq = (dq_c - num2(&r->a[DQ_PREV], i, j)) / h;
    double dddq = (ddq - num2(&r->a[DDQ_PREV], i, j)) / h;
    double start = first ? dq_c - num2(&r->a[START], i, j) : 0.0;
    double upper, lower;
    /* docs/limits.md §4: evaluated at q_d on the joint-velocity interface too */
    envelope(k, j, num2(&r->a[Q_PREV], i, j), r->positional, r->shift, &upper, &lower);
    term(t, 0, dq_c, INFINITY, -INFINITY);
    term(t, 1, start, r->tolerance, -r->tolerance);
    term(t, 2, ddq, ddq_max, -ddq_max);
    term(t, 3, dddq, dddq_max, -dddq_max);
    term(t, 4, dq_c, upper, lower);
    d[1] = ddq;
    unsigned bits = 0;
    if (!isfinite(dq_c)) bits |= 1u;
    if (first && fabs(start) > r->tolerance) bits |= 2u;
    if (fabs(ddq) > ddq_max) bits |= 4u;
    if (fabs(dddq) > dddq_max) bits |= 8u;
    /* "not inside": NaN trips it too */
    if (!((dq_c <= upper) & (dq_c >= lower))) bits |= 16u;
    return bits;
}

/* One generator: its rows, their errors, which apply when, which are symmetric. */
typedef struct {
    int velocity; /* 0: q_c's rows, 1: dq_c's */
    const long long *codes;
    const unsigned *gate;
    unsigned symmetric;
    const char *name;
} Generator;

static const Generator POSITION = {0, POSITION_CODES, POSITION_GATE,
                                   POSITION_SYMMETRIC, "position_rule"};
static const Generator VELOCITY = {1, VELOCITY_CODES, VELOCITY_GATE,
                                   VELOCITY_SYMMETRIC, "velocity_rule"};

/* The generator's rows on robot i's joint j (a direct call, so that the rule's loop
 * inlines it and keeps only the terms it reads). */
static ALWAYS_INLINE unsigned joint_rows(
    const Generator *g, const Joint *r, Py_ssize_t i, int j, int first, double h, Terms *t,
    double d[2])
{
    return g->velocity ? velocity_joint(r, i, j, first, h, t, d)
                       : position_joint(r, i, j, first, h, t, d);
}

/* The first applying row among ``bits``, or -1. */
static inline int winner(unsigned live)
{
    if (!live) return -1;
    int k = 0;
    while (!(live & 1u)) live >>= 1, k++;
    return k;
}

/* position_rule / velocity_rule: error, and dq (q_c only) and ddq. Inlined into each with
 * its generator a constant. */
static ALWAYS_INLINE PyObject *joint_rule(PyObject *const *args, Py_ssize_t nargs, const Generator *g)
{
    Joint r;
    const int with_dq = !g->velocity;
    PyObject *arrays[3] = {NULL, NULL, NULL}, *result = NULL;
    Py_buffer views[3] = {{0}};
    memset(&r, 0, sizeof(r));
    if (check_nargs(nargs, 12, g->name) < 0 || numpy_refs() < 0) return NULL;
    if (joint_get(args, &r) < 0) goto done;
    arrays[0] = empty(r.n, 0, np_int64);
    arrays[1] = arrays[0] ? empty(r.n, 7, np_float64) : NULL;
    arrays[2] = arrays[1] && with_dq ? empty(r.n, 7, np_float64) : NULL;
    for (int a = 0; a < 2 + with_dq; a++)
        if (!arrays[a] ||
            PyObject_GetBuffer(arrays[a], &views[a], PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0)
            goto done;
    long long *error = views[0].buf;
    double *ddq_out = views[1].buf, *dq_out = with_dq ? views[2].buf : NULL;
    for (Py_ssize_t i = 0; i < r.n; i++) {
        const int first = per_robot_at(&r.first, i) != 0.0;
        const double h = per_robot_at(&r.steps, i) * r.dt;
        unsigned bits = 0;
        for (int j = 0; j < 7; j++) {
            double d[2];
            bits |= joint_rows(g, &r, i, j, first, h, NULL, d);
            /* at rest on the opening command (np.where's +0.0) */
            ddq_out[i * 7 + j] = first ? 0.0 : d[1];
            if (with_dq) dq_out[i * 7 + j] = first ? 0.0 : d[0];
        }
        int k = winner(bits & g->gate[first]);
        error[i] = k < 0 ? NO_ERROR : g->codes[k];
    }
    result = with_dq ? Py_BuildValue("(OOO)", arrays[0], arrays[2], arrays[1])
                     : Py_BuildValue("(OO)", arrays[0], arrays[1]);
done:
    for (int a = 0; a < 3; a++) {
        if (views[a].obj) PyBuffer_Release(&views[a]);
        Py_XDECREF(arrays[a]);
    }
    joint_release(&r);
    return result;
}

/* position_detail / velocity_detail: robot i's winning row, joint, value and bound. */
static PyObject *joint_detail(PyObject *const *args, Py_ssize_t nargs, const Generator *g,
                              const char *name)
{
    Joint r;
    PyObject *result = NULL;
    memset(&r, 0, sizeof(r));
    if (check_nargs(nargs, 13, name) < 0) return NULL;
    Py_ssize_t i;
    if (robot_index(args[0], &i) < 0) return NULL;
    if (joint_get(args + 1, &r) < 0 || robot_in_range(i, r.n, name) < 0) goto done;
    const int first = per_robot_at(&r.first, i) != 0.0;
    const double h = per_robot_at(&r.steps, i) * r.dt;
    Terms t[7];
    unsigned bits[7], any = 0;
    double d[2];
    for (int j = 0; j < 7; j++) any |= bits[j] = joint_rows(g, &r, i, j, first, h, &t[j], d);
    int k = winner(any & g->gate[first]);
    if (k < 0) {
        result = Py_NewRef(Py_None);
        goto done;
    }
    int worst = -1;
    double excess = -INFINITY;
    for (int j = 0; j < 7; j++) {
        if (!(bits[j] & (1u << k))) continue;
        double value = t[j].value[k];
        if (!isfinite(value)) { /* no distance to a bound: the first such joint */
            result = Py_BuildValue("(Liidd)", g->codes[k], k, j, value, NAN);
            goto done;
        }
        double x = nan_max(value - t[j].upper[k], t[j].lower[k] - value);
        if (worst < 0 || (isnan(x) && !isnan(excess)) || x > excess) worst = j, excess = x;
    }
    const Terms *w = &t[worst];
    double value = w->value[k];
    int above = value - w->upper[k] >= w->lower[k] - value;
    double limit = (above || (g->symmetric >> k & 1u)) ? w->upper[k] : w->lower[k];
    result = Py_BuildValue("(Liidd)", g->codes[k], k, worst, value, limit);
done:
    joint_release(&r);
    return result;
}

static PyObject *position_rule(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return joint_rule(args, nargs, &POSITION);
}
static PyObject *velocity_rule(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return joint_rule(args, nargs, &VELOCITY);
}
static PyObject *position_detail(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return joint_detail(args, nargs, &POSITION, "position_detail");
}
static PyObject *velocity_detail(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return joint_detail(args, nargs, &VELOCITY, "velocity_detail");
}

/* ---- the joint generators' cycle: the lost-cycle laws and the reference's record ------ */

/* docs/fci-behaviour.md "What the sim does with a lost cycle": a signal the client did not
 * send this cycle continues at the acceleration the last two real commands implied, frozen
 * (libfranka docs/system_requirements.rst: "keep acceleration constant and integrate").
 * dq_c's law: v' = v + a dt. q_c's (and a pose's translation, elbow[0]): semi-implicit, v'
 * by dq_c's law, then x' = x + v' dt. Their only text (fci/extrapolation.py hands the
 * Cartesian laws these). */
static inline double velocity_law(double v, double a, double dt) { return v + a * dt; }

static inline void position_law(double x, double v, double a, double dt, double *x1, double *v1)
{
    *v1 = velocity_law(v, a, dt);
    *x1 = x + *v1 * dt;
}

/* The joint reference (fci/reference.py JointReference): q_d, dq_d, ddq_d as published,
 * the frozen acceleration, the last real sample (kept while a run of guesses lasts), the
 * id the last real command echoed, and the length of the run. */
enum { R_Q, R_DQ, R_DDQ, R_FROZEN, R_REAL_Q, R_REAL_DQ, R_REAL_DDQ, R_ARRAYS };

typedef struct {
    F64 a[R_ARRAYS];
    Int64s real_echo, run;
} Reference;

static void reference_release(Reference *r)
{
    f64_release_all(r->a, R_ARRAYS);
    int64s_release(&r->real_echo);
    int64s_release(&r->run);
}

/* Borrow the reference from args[0..8]: q, dq, ddq, ddq_frozen, real_q, real_dq, real_ddq,
 * real_echo, run. */
static int reference_get(PyObject *const *args, Py_ssize_t n, Reference *r)
{
    static const char *names[R_ARRAYS] = {"q", "dq", "ddq", "ddq_frozen", "real_q", "real_dq",
                                          "real_ddq"};
    Py_ssize_t s7[2] = {n, 7};
    memset(r, 0, sizeof(*r));
    for (int k = 0; k < R_ARRAYS; k++)
        if (f64_get(args[k], &r->a[k], 2, s7, 1, names[k]) < 0) return -1;
    if (int64s_get(args[7], &r->real_echo, n, 1, "real_echo") < 0 ||
        int64s_get(args[8], &r->run, n, 1, "run") < 0)
        return -1;
    return 0;
}

/* Record robot i's cycle (docs/fci-behaviour.md "The difference formulas", "What the sim
 * does with a lost cycle"): the reference moves to (q, dq, ddq). A real command
 * (``real``) re-freezes the acceleration ("Frozen, not continued"), ends any run of guesses
 * and is the last real sample; a guess extends the run, the first guess of a run keeping
 * the real sample it replaces (a late datagram rewinds to it: "A datagram that turns up
 * late replaces the guess it stood in for"). */
static inline void record_row(const Reference *r, Py_ssize_t i, int real, const double q[7],
                              const double dq[7], const double ddq[7], long long echo)
{
    const F64 *a = r->a;
    if (!real && INT64_AT(r->run, i) == 0)
        for (int j = 0; j < 7; j++) {
            AT2(a[R_REAL_Q], i, j) = AT2(a[R_Q], i, j);
            AT2(a[R_REAL_DQ], i, j) = AT2(a[R_DQ], i, j);
            AT2(a[R_REAL_DDQ], i, j) = AT2(a[R_DDQ], i, j);
        }
    if (real) {
        INT64_AT(r->run, i) = 0;
        INT64_AT(r->real_echo, i) = echo;
    } else {
        INT64_AT(r->run, i) += 1;
    }
    for (int j = 0; j < 7; j++) {
        AT2(a[R_Q], i, j) = q[j];
        AT2(a[R_DQ], i, j) = dq[j];
        AT2(a[R_DDQ], i, j) = ddq[j];
        if (real) AT2(a[R_FROZEN], i, j) = ddq[j];
    }
}

/* JointCycle(aborted, first, lost_run, max_lost, q, dq, ddq, ddq_frozen, real_q, real_dq,
 *            real_ddq, real_echo, run, constants, positional, shift, dt,
 *            error, candidate, new_q, new_dq, new_ddq)
 * JointCycle.advance(q_c, dq_c, have, started, tracking, joint_position, joint_velocity, echo,
 *                    extrapolate_lost, position_tolerance, velocity_tolerance) -> pending
 *
 * One cycle of the joint generators (fci/joint_generators.py JointGenerators.advance), as a
 * plan over the arrays that stay (the engine's pending verdicts, the cycle's first-command
 * flags, the accounting's lost runs, the reference, the table's constants and the outputs:
 * their owners write them in place, never rebind them); each call hands over what changes:
 * the commands, the robots they are for, the modes' masks (Modes.regroup rebinds them), the
 * echo and the configured tolerances. For every robot whose motion tracks (``tracking`` and
 * not ``aborted`` by a pending verdict):
 *
 * - ``have``: its command (q_c or dq_c, echoing ``echo``) is the candidate;
 * - else, when ``extrapolate_lost`` and its motion has ``started``, the cycle is lost: the
 *   candidate is the lost-cycle law's guess while its run of lost cycles (``lost_run``) is
 *   under ``max_lost`` (docs/fci-behaviour.md "Extrapolation stops at 20"), past it the
 *   reference holds at rest (dq, ddq zeroed, nothing judged);
 * - the candidate is judged by its generator's rows (position_rule / velocity_rule, the
 *   same texts) against the reference over one cycle, ``first`` marking the opening command
 *   (read only where ``have``), and the reference recorded: a q_c command moves it to q_c
 *   with the derivatives it implies, a dq_c command to q_d + dq_c dt, dq_c, its ddq; a guess
 *   to the law's q and dq at the frozen acceleration.
 *
 * A robot whose candidate trips a row is not recorded: ``error`` holds its error (-1 for
 * every other robot), ``candidate`` (the judged q_c or dq_c), ``new_q`` / ``new_dq`` /
 * ``new_ddq`` what it would record, and the count of such robots is returned, for the
 * caller to judge (the engine) and record those the verdicts leave running
 * (joint_record). */
enum { Q_C, DQ_C, IN_ARRAYS };
enum { HAVE, STARTED, TRACKING, ABORTED, POSITION_MODE, VELOCITY_MODE, FIRST, FLAGS };
enum { CANDIDATE, NEW_Q, NEW_DQ, NEW_DDQ, OUT_ARRAYS };

typedef struct {
    PyObject_HEAD
    Py_ssize_t n;
    F64 in[IN_ARRAYS], out[OUT_ARRAYS], constants;
    Bytes flags[FLAGS];
    PerRobot lost_run;
    Int64s echo, error;
    Reference ref;
    double extrapolate_lost, max_lost, positional, position_tolerance, velocity_tolerance,
        shift, dt;
} JointCycleObject;

/* The per-call arguments' borrows (the plan's own stay). */
static void cycle_release_call(JointCycleObject *a)
{
    f64_release_all(a->in, IN_ARRAYS);
    bytes_release(&a->flags[HAVE]);
    bytes_release(&a->flags[STARTED]);
    bytes_release(&a->flags[TRACKING]);
    bytes_release(&a->flags[POSITION_MODE]);
    bytes_release(&a->flags[VELOCITY_MODE]);
    int64s_release(&a->echo);
}

static void JointCycle_dealloc(JointCycleObject *self)
{
    cycle_release_call(self);
    f64_release_all(self->out, OUT_ARRAYS);
    f64_release(&self->constants);
    for (int k = 0; k < FLAGS; k++) bytes_release(&self->flags[k]);
    per_robot_release(&self->lost_run);
    int64s_release(&self->error);
    reference_release(&self->ref);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *JointCycle_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "JointCycle() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 22, "JointCycle") < 0) return NULL;
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    Py_ssize_t n = leading(v[0], "aborted");
    if (n < 0) return NULL;
    JointCycleObject *self = (JointCycleObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    Py_ssize_t s7[2] = {n, 7}, sc[2] = {N_CONSTANTS, 7};
    static const char *out_names[OUT_ARRAYS] = {"candidate", "new_q", "new_dq", "new_ddq"};
    if (bytes_get(v[0], &self->flags[ABORTED], n, 0, "aborted") < 0 ||
        bytes_get(v[1], &self->flags[FIRST], n, 0, "first") < 0 ||
        per_robot_get(v[2], &self->lost_run, n, "lost_run") < 0 ||
        number(v[3], &self->max_lost, "max_lost") < 0 || reference_get(v + 4, n, &self->ref) < 0 ||
        f64_get(v[13], &self->constants, 2, sc, 0, "constants") < 0 ||
        number(v[14], &self->positional, "positional") < 0 ||
        number(v[15], &self->shift, "shift") < 0 || number(v[16], &self->dt, "dt") < 0 ||
        int64s_get(v[17], &self->error, n, 1, "error") < 0)
        goto fail;
    for (int k = 0; k < OUT_ARRAYS; k++)
        if (f64_get(v[18 + k], &self->out[k], 2, s7, 1, out_names[k]) < 0) goto fail;
    return (PyObject *)self;
fail:
    Py_DECREF(self);
    return NULL;
}

/* The loop of one cycle over the plan's arrays, the call's borrowed. */
static long long advance_rows(JointCycleObject *a)
{
    const Py_ssize_t n = a->n;
    F64 *in = a->in, *out = a->out;
    const Bytes *flags = a->flags;
    const double dt = a->dt, extrapolate_lost = a->extrapolate_lost, max_lost = a->max_lost;
    const PerRobot lost_run = a->lost_run;
    const Int64s echo = a->echo, error = a->error;
    const Reference ref = a->ref;
    const F64 constants = a->constants;
    const double positional = a->positional, position_tolerance = a->position_tolerance;
    const double velocity_tolerance = a->velocity_tolerance, shift = a->shift;
    /* The generators' rows read the candidate against the reference as it stands (the
     * rules' arguments: start = q_d for q_c, dq_d for dq_c; one cycle). */
    Joint rp, rv;
    memset(&rp, 0, sizeof(rp));
    rp.n = n;
    rp.a[CMD] = out[CANDIDATE];
    rp.a[Q_PREV] = ref.a[R_Q];
    rp.a[DQ_PREV] = ref.a[R_DQ];
    rp.a[DDQ_PREV] = ref.a[R_DDQ];
    rp.a[START] = ref.a[R_Q];
    rp.a[CONSTANTS] = constants;
    rp.positional = positional != 0.0;
    rp.tolerance = position_tolerance;
    rp.shift = shift;
    rp.dt = dt;
    rv = rp;
    rv.a[START] = ref.a[R_DQ];
    rv.tolerance = velocity_tolerance;
    const F64 *r = ref.a;
    long long pending = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        INT64_AT(error, i) = NO_ERROR;
        const int live = BYTE1(flags[TRACKING], i) && !BYTE1(flags[ABORTED], i);
        const int have = BYTE1(flags[HAVE], i) != 0;
        const int lost = extrapolate_lost != 0.0 && BYTE1(flags[STARTED], i) && !have && live;
        const int guess = lost && per_robot_at(&lost_run, i) < max_lost;
        const int moves = (have || guess) && live;
        const int position = moves && BYTE1(flags[POSITION_MODE], i);
        const int velocity = moves && !position && BYTE1(flags[VELOCITY_MODE], i);
        if (!position && !velocity) {
            if (lost && !guess) /* past the last guess: held at rest */
                for (int j = 0; j < 7; j++) AT2(r[R_DQ], i, j) = 0.0, AT2(r[R_DDQ], i, j) = 0.0;
            continue;
        }
        const int first = have && BYTE1(flags[FIRST], i);
        double guess_q[7], guess_dq[7], q[7], dq[7], ddq[7];
        for (int j = 0; j < 7; j++) {
            position_law(AT2(r[R_Q], i, j), AT2(r[R_DQ], i, j), AT2(r[R_FROZEN], i, j), dt,
                         &guess_q[j], &guess_dq[j]);
            double command = num2(&in[position ? Q_C : DQ_C], i, j);
            AT2(out[CANDIDATE], i, j) = have ? command : (position ? guess_q[j] : guess_dq[j]);
        }
        unsigned bits = 0;
        for (int j = 0; j < 7; j++) {
            double d[2] = {0.0, 0.0};
            const double frozen = AT2(r[R_FROZEN], i, j);
            if (position) {
                bits |= position_joint(&rp, i, j, first, dt, NULL, d);
                q[j] = AT2(out[CANDIDATE], i, j);
                dq[j] = have ? (first ? 0.0 : d[0]) : guess_dq[j];
            } else {
                bits |= velocity_joint(&rv, i, j, first, dt, NULL, d);
                const double dq_c = AT2(out[CANDIDATE], i, j);
                /* a dq_c command moves q_d by one cycle of it (the same Euler step) */
                q[j] = have ? velocity_law(AT2(r[R_Q], i, j), dq_c, dt) : guess_q[j];
                dq[j] = have ? dq_c : guess_dq[j];
            }
            ddq[j] = have ? (first ? 0.0 : d[1]) : frozen;
        }
        const Generator *g = position ? &POSITION : &VELOCITY;
        const int k = winner(bits & g->gate[first]);
        if (k >= 0) { /* for the engine: judged, then recorded unless aborted */
            INT64_AT(error, i) = g->codes[k];
            for (int j = 0; j < 7; j++) {
                AT2(out[NEW_Q], i, j) = q[j];
                AT2(out[NEW_DQ], i, j) = dq[j];
                AT2(out[NEW_DDQ], i, j) = ddq[j];
            }
            pending++;
            continue;
        }
        record_row(&ref, i, have, q, dq, ddq, INT64_AT(echo, i));
    }
    return pending;
}

static PyObject *JointCycle_advance(JointCycleObject *self, PyObject *const *args,
                                    Py_ssize_t nargs)
{
    if (check_nargs(nargs, 11, "advance") < 0) return NULL;
    Py_ssize_t n = self->n, s7[2] = {n, 7};
    PyObject *result = NULL;
    if (num_get(args[0], &self->in[Q_C], 2, s7, 0, "q_c") < 0 ||
        num_get(args[1], &self->in[DQ_C], 2, s7, 0, "dq_c") < 0 ||
        bytes_get(args[2], &self->flags[HAVE], n, 0, "have") < 0 ||
        bytes_get(args[3], &self->flags[STARTED], n, 0, "started") < 0 ||
        bytes_get(args[4], &self->flags[TRACKING], n, 0, "tracking") < 0 ||
        bytes_get(args[5], &self->flags[POSITION_MODE], n, 0, "joint_position") < 0 ||
        bytes_get(args[6], &self->flags[VELOCITY_MODE], n, 0, "joint_velocity") < 0 ||
        int64s_get(args[7], &self->echo, n, 0, "echo") < 0 ||
        number(args[8], &self->extrapolate_lost, "extrapolate_lost") < 0 ||
        number(args[9], &self->position_tolerance, "position_tolerance") < 0 ||
        number(args[10], &self->velocity_tolerance, "velocity_tolerance") < 0)
        goto done;
    result = PyLong_FromLongLong(advance_rows(self));
done:
    cycle_release_call(self);
    return result;
}

static PyMethodDef JOINT_CYCLE_METHODS[] = {
    {"advance", (PyCFunction)(void (*)(void))JointCycle_advance, METH_FASTCALL,
     "advance(q_c, dq_c, have, started, tracking, joint_position, joint_velocity, echo, "
     "extrapolate_lost, position_tolerance, velocity_tolerance) -> pending: one cycle of the "
     "joint generators."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject JointCycleType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.fci.limits._joint.JointCycle",
    .tp_basicsize = sizeof(JointCycleObject),
    .tp_dealloc = (destructor)JointCycle_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "JointCycle(aborted, first, lost_run, max_lost, <the reference>, "
              "constants, positional, shift, dt, error, candidate, new_q, new_dq, new_ddq): "
              "the joint generators' cycle.",
    .tp_methods = JOINT_CYCLE_METHODS,
    .tp_new = JointCycle_new,
};

/* joint_record(rows, have, new_q, new_dq, new_ddq, echo, q, dq, ddq, ddq_frozen, real_q,
 *              real_dq, real_ddq, real_echo, run)
 *
 * Record the cycle of ``rows`` (JointCycle.advance's pending robots that the verdicts left
 * running) from what JointCycle.advance left in new_q / new_dq / new_ddq: a real command where
 * ``have``, else a guess. */
static PyObject *joint_record(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { NEW_Q, NEW_DQ, NEW_DDQ, NEW_ARRAYS };
    F64 next[NEW_ARRAYS];
    Bytes rows, have;
    Int64s echo;
    Reference ref;
    memset(next, 0, sizeof(next));
    memset(&rows, 0, sizeof(rows));
    memset(&have, 0, sizeof(have));
    memset(&echo, 0, sizeof(echo));
    memset(&ref, 0, sizeof(ref));
    PyObject *result = NULL;
    if (check_nargs(nargs, 15, "joint_record") < 0) return NULL;
    Py_ssize_t n = leading(args[2], "new_q");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7};
    static const char *names[NEW_ARRAYS] = {"new_q", "new_dq", "new_ddq"};
    if (bytes_get(args[0], &rows, n, 0, "rows") < 0 || bytes_get(args[1], &have, n, 0, "have") < 0)
        goto done;
    for (int k = 0; k < NEW_ARRAYS; k++)
        if (f64_get(args[2 + k], &next[k], 2, s7, 0, names[k]) < 0) goto done;
    if (int64s_get(args[5], &echo, n, 0, "echo") < 0 || reference_get(args + 6, n, &ref) < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!BYTE1(rows, i)) continue;
        double q[7], dq[7], ddq[7];
        for (int j = 0; j < 7; j++) {
            q[j] = AT2(next[NEW_Q], i, j);
            dq[j] = AT2(next[NEW_DQ], i, j);
            ddq[j] = AT2(next[NEW_DDQ], i, j);
        }
        record_row(&ref, i, BYTE1(have, i) != 0, q, dq, ddq, INT64_AT(echo, i));
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(next, NEW_ARRAYS);
    bytes_release(&rows);
    bytes_release(&have);
    int64s_release(&echo);
    reference_release(&ref);
    return result;
}

/* position_step(x, v, a, dt) -> (x', v') and velocity_step(v, a, dt) -> v': the q_c and
 * dq_c laws above on (m,) or (m, k) float64 arrays of one shape (the Cartesian generators'
 * translation, elbow and twist: fci/extrapolation.py). */
static PyObject *law_call(PyObject *const *args, Py_ssize_t nargs, int position)
{
    const char *name = position ? "position_step" : "velocity_step";
    const int arrays = position ? 3 : 2;
    F64 a[3];
    memset(a, 0, sizeof(a));
    PyObject *out[2] = {NULL, NULL}, *result = NULL;
    Py_buffer views[2] = {{0}};
    double dt;
    if (check_nargs(nargs, arrays + 1, name) < 0 || numpy_refs() < 0) return NULL;
    Py_buffer probe;
    if (PyObject_GetBuffer(args[0], &probe, PyBUF_RECORDS_RO) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected a float64 array", name);
        return NULL;
    }
    int ndim = probe.ndim;
    Py_ssize_t shape[2] = {ndim >= 1 ? probe.shape[0] : 0, ndim == 2 ? probe.shape[1] : 1};
    PyBuffer_Release(&probe);
    if (ndim != 1 && ndim != 2) {
        PyErr_Format(PyExc_ValueError, "%s: expected 1-D or 2-D arrays", name);
        return NULL;
    }
    static const char *names[3] = {"x", "v", "a"};
    for (int k = 0; k < arrays; k++)
        if (f64_get(args[k], &a[k], ndim, shape, 0, names[k + !position]) < 0) goto done;
    if (number(args[arrays], &dt, "dt") < 0) goto done;
    for (int k = 0; k < 1 + position; k++) {
        out[k] = empty(shape[0], ndim == 2 ? shape[1] : 0, np_float64);
        if (!out[k] || PyObject_GetBuffer(out[k], &views[k], PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0)
            goto done;
    }
    for (Py_ssize_t i = 0; i < shape[0]; i++)
        for (Py_ssize_t j = 0; j < shape[1]; j++) {
            const Py_ssize_t at = i * shape[1] + j;
#define ELEMENT(arr) (ndim == 2 ? AT2(arr, i, j) : AT1(arr, i))
            if (position) {
                double *x1 = views[0].buf, *v1 = views[1].buf;
                position_law(ELEMENT(a[0]), ELEMENT(a[1]), ELEMENT(a[2]), dt, &x1[at], &v1[at]);
            } else {
                double *v1 = views[0].buf;
                v1[at] = velocity_law(ELEMENT(a[0]), ELEMENT(a[1]), dt);
            }
#undef ELEMENT
        }
    result = position ? Py_BuildValue("(OO)", out[0], out[1]) : Py_NewRef(out[0]);
done:
    for (int k = 0; k < 2; k++) {
        if (views[k].obj) PyBuffer_Release(&views[k]);
        Py_XDECREF(out[k]);
    }
    f64_release_all(a, 3);
    return result;
}

static PyObject *position_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return law_call(args, nargs, 1);
}
static PyObject *velocity_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return law_call(args, nargs, 0);
}

/* ---- the safety controller's velocity halves: the rules' only text ------------------- */

enum { E3 = 3, E4 = 4 };

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
    error = empty(s.n, 0, np_int64);
    bad = error ? empty(s.n, 0, np_bool) : NULL;
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

/* SafetyPlan(dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, dt, error,
 *            bad): safety_rule's arrays held (safety_controller.py, every cycle of a motion),
 * its outputs written into error (n,) int64 and bad (n,) uint8; run(in_motion) -> count.
 * The same safety_error as safety_rule and safety_detail: one text of the rule. */
typedef struct {
    PyObject_HEAD
    Safety s;
    Int64s error;
    Bytes bad;
} SafetyPlanObject;

static void SafetyPlan_dealloc(SafetyPlanObject *self)
{
    f64_release_all(self->s.a, S_ARRAYS);
    int64s_release(&self->error);
    bytes_release(&self->bad);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *SafetyPlan_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "SafetyPlan() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 12, "SafetyPlan") < 0) return NULL;
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    SafetyPlanObject *self = (SafetyPlanObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    if (safety_get(v, &self->s) < 0 ||
        int64s_get(v[10], &self->error, self->s.n, 1, "error") < 0 ||
        bytes_get(v[11], &self->bad, self->s.n, 1, "bad") < 0) {
        Py_DECREF(self);
        return NULL;
    }
    return (PyObject *)self;
}

static PyObject *SafetyPlan_run(SafetyPlanObject *self, PyObject *in_motion)
{
    Bytes motion;
    if (bytes_get(in_motion, &motion, self->s.n, 0, "in_motion") < 0) return NULL;
    Py_ssize_t count = 0;
    for (Py_ssize_t i = 0; i < self->s.n; i++) {
        long long e = safety_error(&self->s, i);
        int b = e != NO_ERROR && BYTE1(motion, i);
        INT64_AT(self->error, i) = e;
        self->bad.data[i * self->bad.stride] = (char)b;
        count += b;
    }
    bytes_release(&motion);
    return PyLong_FromSsize_t(count);
}

static PyMethodDef SAFETY_PLAN_METHODS[] = {
    {"run", (PyCFunction)SafetyPlan_run, METH_O,
     "run(in_motion) -> the bad robots: errors 3 and 4 into error, bad."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject SafetyPlanType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.fci.limits._joint.SafetyPlan",
    .tp_basicsize = sizeof(SafetyPlanObject),
    .tp_dealloc = (destructor)SafetyPlan_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "SafetyPlan(dq, q, ee, ee_prev, constants, positional, shift, margin, v_max, "
              "dt, error, bad): safety_rule planned; run(in_motion).",
    .tp_methods = SAFETY_PLAN_METHODS,
    .tp_new = SafetyPlan_new,
};

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

/* The rules' arguments: tau_c, tau_prev, steps, tau_max, dtau_max, dt from args[0]. */
enum { T_TAU, T_PREV, T_MAX, T_ARRAYS };

typedef struct {
    F64 a[T_ARRAYS];
    PerRobot steps;
    double dtau_max, dt;
    Py_ssize_t n;
} Torque;

static void torque_release(Torque *t)
{
    f64_release_all(t->a, T_ARRAYS);
    per_robot_release(&t->steps);
}

static int torque_get(PyObject *const *args, Torque *t)
{
    memset(t, 0, sizeof(*t));
    Py_ssize_t n = t->n = leading(args[0], "tau_c");
    if (n < 0) return -1;
    Py_ssize_t s7[2] = {n, 7}, s1[1] = {7};
    if (num_get(args[0], &t->a[T_TAU], 2, s7, 0, "tau_c") < 0 ||
        num_get(args[1], &t->a[T_PREV], 2, s7, 0, "tau_prev") < 0 ||
        per_robot_get(args[2], &t->steps, n, "steps") < 0 ||
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
    const double h = per_robot_at(&t->steps, i) * t->dt;
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
    error = empty(t.n, 0, np_int64);
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

/* ---- the Cartesian generators' tables: the rules' only text ---------------------------- */

/* cartesian_rule(kind, codes, stacked, first, start_pose, start_elbow, elbow, elbow_has,
 *                elbow_had, elbow_prev_flag, elbow_v, elbow_a, elbow_jerk, ik, checked,
 *                solved, q, dq, q_prev, limits2, elbow_limits, ik_limits, constants,
 *                positional, shift) -> None | (error, tripped)
 *
 * fci/limits/cartesian.py check_cartesian_pose (kind 0) / check_cartesian_velocity (kind 1),
 * which name the rows and hand over the table's constants; docs/fci-behaviour.md "What is
 * checked, and what it latches" and "The joint side of a Cartesian command". Per robot:
 *
 *   the Cartesian norms: ``stacked`` (n, 3, 6) [[v | omega], [a | alpha], [jerk | zeta]],
 *     each half's squared norm (x0 x0 + x1 x1 + x2 x2, the order numpy's einsum summed)
 *     within ``limits2`` (6,) [v, omega, a, alpha, jerk, zeta]^2 ("within", so a NaN trips);
 *     the pose's only after its opening command (``first``), the twist's always (its
 *     opening twist is an acceleration from standstill);
 *   the joint side of the IK solution: 27 its ``q`` (n, 7) outside constants' range where
 *     ``solved`` (None: where ``checked``); 29 / 30 ``ik`` (n, 2, 7) [ddq, dddq] over
 *     ``ik_limits`` (2, 7), 28 its ``dq`` outside the velocity envelope at ``q_prev`` (the
 *     law above, ``shift`` its tolerance), where ``checked``; ``q`` / ``dq`` / ``q_prev`` None:
 *     27 and 28 off;
 *   the elbow, where ``elbow_has``: 21 the branch flag elbow[:, 1] not ``elbow_prev_flag``
 *     on a later command that continues an elbow stream (``elbow_had``); 17 elbow[:, 0]
 *     outside joint 3's range (always), or on such a command |v|, |a|, |jerk| over
 *     ``elbow_limits`` (3,) (kMaxElbowVelocity, -Acceleration, -Jerk);
 *   the start rows (the pose's 16, 22), judged by the caller on the opening command and
 *     passed in (None: not tripped).
 *
 * Rows in ``codes``' order (the tables of cartesian.py): pose [16, 22, 21, 19, 18, 20, 27,
 * 29, 28, 30, 17], twist [20 (acceleration), 20 (jerk), 18, 27, 30 (29's or 30's values), 28,
 * 21, 17]; the first tripped row's code is the robot's error. None when no robot tripped
 * any row (the common case), else error (n,) int64 (-1: none) and tripped (n, rows) bool. */
enum { POSE_KIND = 0, TWIST_KIND = 1 };
enum { POSE_TABLE_ROWS = 11, TWIST_TABLE_ROWS = 8 };
enum { C_STACKED, C_ELBOW, C_PREV_FLAG, C_EV, C_EA, C_EJ, C_IK, C_Q, C_DQ, C_QPREV, C_LIMITS2,
       C_ELBOW_LIMITS, C_IK_LIMITS, C_CONSTANTS, C_ARRAYS };
enum { F_FIRST, F_START_POSE, F_START_ELBOW, F_HAS, F_HAD, F_CHECKED, F_SOLVED, F_FLAGS };

typedef struct {
    F64 a[C_ARRAYS];
    Bytes f[F_FLAGS];
    int present[F_FLAGS]; /* the optional flags given (not None) */
    int motion;           /* q, dq, q_prev given: rows 27 and 28 judged */
    Py_buffer codes;
    int kind, rows, positional;
    double shift;
    Py_ssize_t n;
} CartesianArgs;

static void cartesian_release(CartesianArgs *c)
{
    f64_release_all(c->a, C_ARRAYS);
    for (int k = 0; k < F_FLAGS; k++) bytes_release(&c->f[k]);
    if (c->codes.obj) PyBuffer_Release(&c->codes);
}

/* A flag argument that may be None (``required`` 0). */
static int flags_get(PyObject *obj, CartesianArgs *c, int k, int required, const char *name)
{
    if (!required && obj == Py_None) return 0;
    if (bytes_get(obj, &c->f[k], c->n, 0, name) < 0) return -1;
    c->present[k] = 1;
    return 0;
}

static int cartesian_get(PyObject *const *args, CartesianArgs *c)
{
    memset(c, 0, sizeof(*c));
    double kind, positional;
    if (number(args[0], &kind, "kind") < 0) return -1;
    c->kind = kind != 0.0;
    c->rows = c->kind == TWIST_KIND ? TWIST_TABLE_ROWS : POSE_TABLE_ROWS;
    if (PyObject_GetBuffer(args[1], &c->codes, PyBUF_C_CONTIGUOUS) < 0) return -1;
    if (c->codes.itemsize != 8 || c->codes.len != 8 * c->rows) {
        PyErr_Format(PyExc_ValueError, "codes: expected %d int64 error codes", c->rows);
        return -1;
    }
    Py_ssize_t n = c->n = leading(args[2], "stacked");
    if (n < 0) return -1;
    Py_ssize_t s36[3] = {n, 3, 6}, s2[2] = {n, 2}, s1[1] = {n}, s27[3] = {n, 2, 7};
    Py_ssize_t s7[2] = {n, 7}, six[1] = {6}, three[1] = {3}, l27[2] = {2, 7};
    Py_ssize_t sc[2] = {N_CONSTANTS, 7};
    if (f64_get(args[2], &c->a[C_STACKED], 3, s36, 0, "stacked") < 0 ||
        flags_get(args[3], c, F_FIRST, 1, "first") < 0 ||
        flags_get(args[4], c, F_START_POSE, 0, "start_pose") < 0 ||
        flags_get(args[5], c, F_START_ELBOW, 0, "start_elbow") < 0 ||
        num_get(args[6], &c->a[C_ELBOW], 2, s2, 0, "elbow") < 0 ||
        flags_get(args[7], c, F_HAS, 1, "elbow_has") < 0 ||
        flags_get(args[8], c, F_HAD, 1, "elbow_had") < 0 ||
        f64_get(args[9], &c->a[C_PREV_FLAG], 1, s1, 0, "elbow_prev_flag") < 0 ||
        f64_get(args[10], &c->a[C_EV], 1, s1, 0, "elbow_v") < 0 ||
        f64_get(args[11], &c->a[C_EA], 1, s1, 0, "elbow_a") < 0 ||
        f64_get(args[12], &c->a[C_EJ], 1, s1, 0, "elbow_jerk") < 0 ||
        f64_get(args[13], &c->a[C_IK], 3, s27, 0, "ik") < 0 ||
        flags_get(args[14], c, F_CHECKED, 1, "checked") < 0 ||
        flags_get(args[15], c, F_SOLVED, 0, "solved") < 0)
        return -1;
    c->motion = args[16] != Py_None;
    if (c->motion &&
        (f64_get(args[16], &c->a[C_Q], 2, s7, 0, "q") < 0 ||
         f64_get(args[17], &c->a[C_DQ], 2, s7, 0, "dq") < 0 ||
         f64_get(args[18], &c->a[C_QPREV], 2, s7, 0, "q_prev") < 0))
        return -1;
    if (f64_get(args[19], &c->a[C_LIMITS2], 1, six, 0, "limits2") < 0 ||
        f64_get(args[20], &c->a[C_ELBOW_LIMITS], 1, three, 0, "elbow_limits") < 0 ||
        f64_get(args[21], &c->a[C_IK_LIMITS], 2, l27, 0, "ik_limits") < 0 ||
        f64_get(args[22], &c->a[C_CONSTANTS], 2, sc, 0, "constants") < 0 ||
        number(args[23], &positional, "positional") < 0 ||
        number(args[24], &c->shift, "shift") < 0)
        return -1;
    c->positional = positional != 0.0;
    return 0;
}

/* Robot i's tripped rows, bit k row k of its kind's table. */
static ALWAYS_INLINE unsigned cartesian_rows(const CartesianArgs *c, Py_ssize_t i)
{
    const F64 *a = c->a;
    const int first = BYTE1(c->f[F_FIRST], i) != 0, later = !first;
    /* The Cartesian norms: bit h half h (v, omega, a, alpha, jerk, zeta) over its limit. */
    unsigned over = 0;
    for (int h = 0; h < 6; h++) {
        const int row = h / 2, col = (h % 2) * 3;
        const double x0 = AT3(a[C_STACKED], i, row, col), x1 = AT3(a[C_STACKED], i, row, col + 1);
        const double x2 = AT3(a[C_STACKED], i, row, col + 2);
        const double s = x0 * x0 + x1 * x1 + x2 * x2;
        if (!(s <= AT1(a[C_LIMITS2], h))) over |= 1u << h;
    }
    if (c->kind == POSE_KIND && first) over = 0;
    const int vel = (over & 3u) != 0, acc = (over & 12u) != 0, jerk = (over & 48u) != 0;
    /* The joint side. */
    const int checked = BYTE1(c->f[F_CHECKED], i) != 0;
    const int solved = c->present[F_SOLVED] ? BYTE1(c->f[F_SOLVED], i) != 0 : checked;
    int r27 = 0, r28 = 0, r29 = 0, r30 = 0;
    const F64 *k = &a[C_CONSTANTS];
    for (int j = 0; j < 7; j++) {
        /* NaN is not over */
        if (fabs(AT3(a[C_IK], i, 0, j)) > AT2(a[C_IK_LIMITS], 0, j)) r29 = 1;
        if (fabs(AT3(a[C_IK], i, 1, j)) > AT2(a[C_IK_LIMITS], 1, j)) r30 = 1;
        if (!c->motion) continue;
        const double q = AT2(a[C_Q], i, j), dq = AT2(a[C_DQ], i, j);
        /* "not inside", so a NaN solution trips (as q_c's 12 does) */
        if (!((q >= AT2(*k, Q_LOWER, j)) & (q <= AT2(*k, Q_UPPER, j)))) r27 = 1;
        double upper, lower;
        /* docs/limits.md §4: at the previous solution, as 13 for q_c at the reference */
        envelope(k, j, AT2(a[C_QPREV], i, j), c->positional, c->shift, &upper, &lower);
        if (!((dq <= upper) & (-dq <= -lower))) r28 = 1;
    }
    r27 &= solved, r28 &= checked, r29 &= checked, r30 &= checked;
    /* The elbow. */
    int sign = 0, elbow = 0;
    if (BYTE1(c->f[F_HAS], i)) {
        const int continuing = later && BYTE1(c->f[F_HAD], i);
        sign = continuing && num2(&a[C_ELBOW], i, 1) != AT1(a[C_PREV_FLAG], i);
        const double e = num2(&a[C_ELBOW], i, 0);
        const int outside = !((e >= AT2(*k, Q_LOWER, 2)) & (e <= AT2(*k, Q_UPPER, 2)));
        const int too_fast = (fabs(AT1(a[C_EV], i)) > AT1(a[C_ELBOW_LIMITS], 0)) |
                             (fabs(AT1(a[C_EA], i)) > AT1(a[C_ELBOW_LIMITS], 1)) |
                             (fabs(AT1(a[C_EJ], i)) > AT1(a[C_ELBOW_LIMITS], 2));
        elbow = outside || (continuing && too_fast);
    }
    if (c->kind == TWIST_KIND)
        return (unsigned)acc | (unsigned)jerk << 1 | (unsigned)vel << 2 | (unsigned)r27 << 3 |
               (unsigned)(r29 | r30) << 4 | (unsigned)r28 << 5 | (unsigned)sign << 6 |
               (unsigned)elbow << 7;
    const int start_pose = c->present[F_START_POSE] && first && BYTE1(c->f[F_START_POSE], i);
    const int start_elbow = c->present[F_START_ELBOW] && first && BYTE1(c->f[F_START_ELBOW], i);
    return (unsigned)start_pose | (unsigned)start_elbow << 1 | (unsigned)sign << 2 |
           (unsigned)acc << 3 | (unsigned)vel << 4 | (unsigned)jerk << 5 | (unsigned)r27 << 6 |
           (unsigned)r29 << 7 | (unsigned)r28 << 8 | (unsigned)r30 << 9 | (unsigned)elbow << 10;
}

static PyObject *cartesian_rule(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    CartesianArgs c;
    PyObject *arrays[2] = {NULL, NULL}, *result = NULL;
    Py_buffer views[2] = {{0}};
    unsigned *bits = NULL;
    memset(&c, 0, sizeof(c));
    if (check_nargs(nargs, 25, "cartesian_rule") < 0 || numpy_refs() < 0) return NULL;
    if (cartesian_get(args, &c) < 0) goto done;
    bits = PyMem_Malloc((size_t)(c.n > 0 ? c.n : 1) * sizeof(unsigned));
    if (!bits) {
        PyErr_NoMemory();
        goto done;
    }
    unsigned any = 0;
    for (Py_ssize_t i = 0; i < c.n; i++) any |= bits[i] = cartesian_rows(&c, i);
    if (!any) { /* nothing tripped anywhere: the common case */
        result = Py_NewRef(Py_None);
        goto done;
    }
    arrays[0] = empty(c.n, 0, np_int64);
    arrays[1] = arrays[0] ? empty(c.n, c.rows, np_bool) : NULL;
    for (int a = 0; a < 2; a++)
        if (!arrays[a] ||
            PyObject_GetBuffer(arrays[a], &views[a], PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0)
            goto done;
    long long *error = views[0].buf;
    unsigned char *tripped = views[1].buf;
    const long long *codes = c.codes.buf;
    for (Py_ssize_t i = 0; i < c.n; i++) {
        for (int r = 0; r < c.rows; r++) tripped[i * c.rows + r] = (bits[i] >> r) & 1u;
        const int w = winner(bits[i]);
        error[i] = w < 0 ? NO_ERROR : codes[w];
    }
    result = Py_BuildValue("(OO)", arrays[0], arrays[1]);
done:
    for (int a = 0; a < 2; a++) {
        if (views[a].obj) PyBuffer_Release(&views[a]);
        Py_XDECREF(arrays[a]);
    }
    PyMem_Free(bits);
    cartesian_release(&c);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(envelope_halves, "The velocity envelope [upper | -lower] at each row of q, into out."),
    METHOD(position_rule, "The latched error of every robot's q_c, and dq, ddq: (error, dq, ddq)."),
    METHOD(velocity_rule, "The latched error of every robot's dq_c, and ddq: (error, ddq)."),
    METHOD(position_detail, "Robot i's q_c error for the log line: (error, row, joint, value, limit)."),
    METHOD(velocity_detail, "Robot i's dq_c error for the log line: (error, row, joint, value, limit)."),
    METHOD(safety_rule, "Errors 3 and 4 of every robot, 4 over 3: (error, bad, count)."),
    METHOD(torque_rule, "Errors 34 and 32 of every robot, 34 over 32: error."),
    METHOD(torque_detail, "Robot i's error 34 or 32 for the log line: (error, joint, value, limit)."),
    METHOD(cartesian_rule, "The Cartesian pose (kind 0) or twist (kind 1) table of every robot: None, or (error, tripped)."),
    METHOD(joint_record, "Record the cycle of the rows JointCycle.advance left to the engine."),
    METHOD(position_step, "q_c's lost-cycle law on arrays: (x + (v + a dt) dt, v + a dt)."),
    METHOD(velocity_step, "dq_c's lost-cycle law on arrays: v + a dt."),
    METHOD(safety_detail, "Robot i's error 3 or 4 for the log line: (error, joint, value, upper, lower)."),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef _joint_definition = {
    PyModuleDef_HEAD_INIT, "_joint",
    "The joint and Cartesian generators', safety controller's and torque interface's rules "
    "and the velocity envelope: their only text (fci/limits).",
    -1, METHODS, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__joint(void)
{
    if (PyType_Ready(&SafetyPlanType) < 0 || PyType_Ready(&JointCycleType) < 0) return NULL;
    PyObject *m = kernel_module(&_joint_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "SafetyPlan", (PyObject *)&SafetyPlanType) < 0 ||
        PyModule_AddObjectRef(m, "JointCycle", (PyObject *)&JointCycleType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
