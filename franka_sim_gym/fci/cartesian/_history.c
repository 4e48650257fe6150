/* The Cartesian history's arithmetic, its one text: the backward differences a
 * Cartesian command is judged on (docs/fci-behaviour.md "The difference formulas", "The
 * joint side of a Cartesian command") and what a judged step leaves in the history
 * (fci/cartesian/record.py). fci/cartesian/step.py and record.py call it; the history's
 * rows are fci/cartesian/reference.py's (n, WIDTH) float64 buffers, their columns handed
 * over once as the layout.
 *
 *   History(buffer, real_echo, run, pose_stack, joint_stack, published, layout, constants)
 *       a plan over the live history (buffer (n, WIDTH); real_echo (n,) uint64, run (n,)
 *       int64: the last real command's echo and the guesses since), the stepper's
 *       scratch (pose_stack (n, 3, 6): [v | omega], [a | alpha], [jerk | zeta];
 *       joint_stack (n, 4, 7): the IK solution q and its dq, ddq, dddq), what the state
 *       publishes of it (published: the twist motions' start pose start_T (n, 4, 4) and
 *       the state's O_T_EE_d, O_T_EE_c (n, 16), O_dP_EE_d, O_dP_EE_c, O_ddP_EE_c (n, 6),
 *       elbow_d, elbow_c (n, 2)), the layout (WIDTH and the first columns of T,
 *       [v | omega | a | alpha], the frozen [a | alpha], twist, dtwist, the frozen dtwist,
 *       the reported twist, its rate, [q_ik | dq_ik | ddq_ik], ik_warm, the elbow, the
 *       elbow flag) and the constants (dt: fci/tables.py DELTA_T;
 *       the IK samples before the acceleration and the jerk are judged: step.py
 *       WARM_ACCELERATION, WARM_JERK; sim/ik.py USABLE_POSITION_ERROR,
 *       USABLE_ROTATION_ERROR; sim/rotations.py NEAR_PI, TURNING_ABOVE, SERIES_BELOW,
 *       SLERP_LINEAR);
 *   History.pose_derivatives(history, T)
 *       pose_stack of the candidate poses T (n, 4, 4, row-major) against a history
 *       (the live buffer or a published one): translation per axis in the base frame,
 *       rotation as the body-frame rotation vector log(R_prev^T R_c), each order over
 *       one cycle (x / dt, as numpy divided);
 *   History.joint_side(history, first, active, converged, checked) -> failed
 *       joint_stack's dq, ddq, dddq of the solution q against the history's IK joint
 *       history; the jerk zeroed where the history is not warm for it (an opening
 *       command, a failed solve, fewer than WARM_JERK samples); checked (n,) written:
 *       where the velocity, acceleration and jerk are judged; returns how many of
 *       ``active`` did not converge (their log line is Python's);
 *   History.record(T, twist, twist_stack, v_ex, w_ex, pose, apply, real, extrapolate,
 *                  first, converged, position_error, rotation_error, echo)
 *       what the robots of ``apply`` leave in the live history (record.py says what and
 *       why); twist_stack None while no twist motion runs, v_ex / w_ex None while no
 *       robot is extrapolated;
 *   History.publish(pose, velocity)
 *       docs/fci-behaviour.md "RobotState fields", the three regimes: for the robots in a
 *       pose motion (pose (n,) bool) O_T_EE_d = O_T_EE_c = the history's pose, in a twist
 *       motion (velocity) the pose the motion started from, both column-major as the
 *       wire; for both O_dP_EE_d = O_dP_EE_c = the reported twist, O_ddP_EE_c its rate,
 *       and elbow_d = elbow_c = the streamed elbow while one is streamed;
 *   usable(converged, position_error, rotation_error, out, position_max, rotation_max)
 *       the IK solutions the servo may follow: converged, or ended within both bounds.
 *
 * Built without fused multiply-adds (setup.py): each difference rounds as written, and the
 * reported rotation R_c omega_body sums as numpy's einsum does (native/_rotation.h dot3,
 * added to +0.0: einsum starts its sum at zero, so an all-negative-zero sum is +0.0). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_arrays.h"
#include "_rotation.h"

/* The layout's columns, in the order History() takes them. */
enum { C_T, C_POSE, C_FROZEN, C_TWIST, C_DTWIST, C_DTWIST_FROZEN, C_REPORTED, C_DREPORTED,
       C_JOINT, C_WARM, C_ELBOW, C_ELBOW_FLAG, C_COUNT };
/* What the state publishes of the history, in the order History() takes them. */
enum { P_START_T, P_POSE_D, P_POSE_C, P_TWIST_D, P_TWIST_C, P_DTWIST_C, P_ELBOW_D, P_ELBOW_C,
       P_COUNT };
/* The constants, in the order History() takes them. */
enum { K_DT, K_WARM_ACCELERATION, K_WARM_JERK, K_USABLE_P, K_USABLE_R, K_ROTATION, K_COUNT = 9 };

typedef struct {
    PyObject_HEAD
    Py_ssize_t n, width;
    Py_ssize_t col[C_COUNT];
    double dt, warm_acceleration, warm_jerk, usable_p, usable_r;
    F64 buffer, pose_stack, joint_stack, published[P_COUNT];
    Int64s real_echo, run;
} HistoryObject;

static inline int usable_solution(int converged, double position_error, double rotation_error,
                                  double position_max, double rotation_max)
{
    return converged || (position_error <= position_max && rotation_error <= rotation_max);
}

/* Row i of a history buffer (rows of contiguous float64, checked on borrowing). */
static inline double *row_of(const F64 *b, Py_ssize_t i)
{
    return (double *)(b->data + i * b->strides[0]);
}

/* Borrow a history buffer of this plan's layout. */
static int history_get(const HistoryObject *self, PyObject *obj, F64 *b, int writable,
                       const char *name)
{
    Py_ssize_t shape[2] = {self->n, self->width};
    if (f64_get(obj, b, 2, shape, writable, name) < 0) return -1;
    if (b->strides[1] != 8) {
        PyErr_Format(PyExc_ValueError, "%s: expected rows of contiguous float64", name);
        f64_release(b);
        return -1;
    }
    return 0;
}

static void History_dealloc(HistoryObject *self)
{
    f64_release(&self->buffer);
    f64_release(&self->pose_stack);
    f64_release(&self->joint_stack);
    f64_release_all(self->published, P_COUNT);
    int64s_release(&self->real_echo);
    int64s_release(&self->run);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int doubles_of(PyObject *tuple, int count, double *out, const char *name)
{
    if (!PyTuple_Check(tuple) || PyTuple_GET_SIZE(tuple) != count) {
        PyErr_Format(PyExc_TypeError, "%s: expected a tuple of %d numbers", name, count);
        return -1;
    }
    for (int k = 0; k < count; k++) {
        out[k] = PyFloat_AsDouble(PyTuple_GET_ITEM(tuple, k));
        if (out[k] == -1.0 && PyErr_Occurred()) return -1;
        if (!isfinite(out[k])) {
            PyErr_Format(PyExc_ValueError, "%s: expected finite numbers", name);
            return -1;
        }
    }
    return 0;
}

static PyObject *History_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "History() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 8, "History") < 0) return NULL;
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    double layout[C_COUNT + 1], k[K_COUNT];
    if (doubles_of(v[6], C_COUNT + 1, layout, "layout") < 0 ||
        doubles_of(v[7], K_COUNT, k, "constants") < 0)
        return NULL;
    if (!PyTuple_Check(v[5]) || PyTuple_GET_SIZE(v[5]) != P_COUNT) {
        PyErr_Format(PyExc_TypeError, "published: expected a tuple of %d arrays", P_COUNT);
        return NULL;
    }
    Py_ssize_t n = leading(v[0], "buffer");
    if (n < 0) return NULL;
    HistoryObject *self = (HistoryObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    /* each block's width, as reference.py's layout lays them out */
    static const Py_ssize_t SIZE[C_COUNT] = {16, 12, 6, 6, 6, 6, 6, 6, 21, 1, 2, 1};
    static const char *const BLOCKS[C_COUNT] = {
        "T", "history", "acceleration_frozen", "twist", "dtwist", "dtwist_frozen",
        "reported", "dreported", "joint", "ik_warm", "elbow", "elbow_flag"};
    for (int c = 0; c <= C_COUNT; c++) /* integers no wider than a row can be */
        if (!(layout[c] >= 0.0 && layout[c] <= 1e6 && layout[c] == floor(layout[c]))) {
            PyErr_Format(PyExc_ValueError, "layout: %s is not a column count",
                         c == 0 ? "the width" : BLOCKS[c - 1]);
            goto fail;
        }
    self->width = (Py_ssize_t)layout[0];
    for (int c = 0; c < C_COUNT; c++) {
        self->col[c] = (Py_ssize_t)layout[c + 1];
        if (self->col[c] + SIZE[c] > self->width) {
            PyErr_Format(PyExc_ValueError, "layout: %s (%zd columns at %zd) does not fit a "
                         "%zd-column row", BLOCKS[c], SIZE[c], self->col[c], self->width);
            goto fail;
        }
    }
    if (!(k[K_DT] > 0.0)) {
        PyErr_SetString(PyExc_ValueError, "constants: dt must be positive");
        goto fail;
    }
    self->dt = k[K_DT];
    self->warm_acceleration = k[K_WARM_ACCELERATION];
    self->warm_jerk = k[K_WARM_JERK];
    self->usable_p = k[K_USABLE_P];
    self->usable_r = k[K_USABLE_R];
    Py_ssize_t s36[3] = {n, 3, 6}, s47[3] = {n, 4, 7};
    if (history_get(self, v[0], &self->buffer, 1, "buffer") < 0 ||
        int64s_get(v[1], &self->real_echo, n, 1, "real_echo") < 0 ||
        int64s_get(v[2], &self->run, n, 1, "run") < 0 ||
        f64_get(v[3], &self->pose_stack, 3, s36, 1, "pose_stack") < 0 ||
        f64_get(v[4], &self->joint_stack, 3, s47, 1, "joint_stack") < 0)
        goto fail;
    static const char *const PUBLISHED[P_COUNT] = {"start_T",   "O_T_EE_d",  "O_T_EE_c",
                                                   "O_dP_EE_d", "O_dP_EE_c", "O_ddP_EE_c",
                                                   "elbow_d",   "elbow_c"};
    Py_ssize_t s44[3] = {n, 4, 4}, s16[2] = {n, 16}, s6[2] = {n, 6}, s2[2] = {n, 2};
    const Py_ssize_t *shapes[P_COUNT] = {s44, s16, s16, s6, s6, s6, s2, s2};
    for (int p = 0; p < P_COUNT; p++)
        if (f64_get(PyTuple_GET_ITEM(v[5], p), &self->published[p], p == P_START_T ? 3 : 2,
                    shapes[p], p != P_START_T, PUBLISHED[p]) < 0)
            goto fail;
    /* sim/rotations.py's thresholds, module-wide (every plan is handed the same ones): set
     * only by a plan that was built */
    rotation_configure(&k[K_ROTATION]);
    return (PyObject *)self;
fail:
    Py_DECREF(self);
    return NULL;
}

/* pose_derivatives(history, T) */
static PyObject *History_pose_derivatives(HistoryObject *self, PyObject *const *args,
                                          Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "pose_derivatives") < 0) return NULL;
    Py_ssize_t n = self->n, s44[3] = {n, 4, 4};
    F64 h, T;
    memset(&T, 0, sizeof(T));
    if (history_get(self, args[0], &h, 0, "history") < 0) return NULL;
    if (f64_get(args[1], &T, 3, s44, 0, "T") < 0) {
        f64_release(&h);
        return NULL;
    }
    const double dt = self->dt;
    const F64 *D = &self->pose_stack;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *row = row_of(&h, i);
        const double *Tp = row + self->col[C_T], *past = row + self->col[C_POSE];
        double Rp[9], Rc[9], v[6];
        for (int r = 0; r < 3; r++) {
            v[r] = AT3(T, i, r, 3) - Tp[4 * r + 3];
            for (int c = 0; c < 3; c++) {
                Rp[3 * r + c] = Tp[4 * r + c];
                Rc[3 * r + c] = AT3(T, i, r, c);
            }
        }
        relative_rotation_log(Rp, Rc, v + 3);
        for (int k = 0; k < 6; k++) {
            double velocity = v[k] / dt;
            double acceleration = (velocity - past[k]) / dt;
            AT3(*D, i, 0, k) = velocity;
            AT3(*D, i, 1, k) = acceleration;
            AT3(*D, i, 2, k) = (acceleration - past[6 + k]) / dt;
        }
    }
    f64_release(&h);
    f64_release(&T);
    Py_RETURN_NONE;
}

/* joint_side(history, first, active, converged, checked) -> failed */
static PyObject *History_joint_side(HistoryObject *self, PyObject *const *args,
                                    Py_ssize_t nargs)
{
    if (check_nargs(nargs, 5, "joint_side") < 0) return NULL;
    Py_ssize_t n = self->n, failed = 0;
    F64 h;
    Bytes first, active, converged, checked;
    memset(&first, 0, sizeof(first));
    memset(&active, 0, sizeof(active));
    memset(&converged, 0, sizeof(converged));
    memset(&checked, 0, sizeof(checked));
    PyObject *result = NULL;
    if (history_get(self, args[0], &h, 0, "history") < 0) return NULL;
    if (bytes_get(args[1], &first, n, 0, "first") < 0 ||
        bytes_get(args[2], &active, n, 0, "active") < 0 ||
        bytes_get(args[3], &converged, n, 0, "converged") < 0 ||
        bytes_get(args[4], &checked, n, 1, "checked") < 0)
        goto done;
    const double dt = self->dt;
    const F64 *S = &self->joint_stack;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *row = row_of(&h, i);
        const double *past = row + self->col[C_JOINT], warm_count = row[self->col[C_WARM]];
        int ok = BYTE1(converged, i) != 0;
        for (int j = 0; j < 7; j++) {
            double dq = (AT3(*S, i, 0, j) - past[j]) / dt;
            double ddq = (dq - past[7 + j]) / dt;
            AT3(*S, i, 1, j) = dq;
            AT3(*S, i, 2, j) = ddq;
            AT3(*S, i, 3, j) = (ddq - past[14 + j]) / dt;
        }
        /* An opening command or a failed solve leaves no history to difference against:
         * the acceleration needs WARM_ACCELERATION samples after a rebase, the jerk
         * WARM_JERK (step.py). */
        int warm = ok && !BYTE1(first, i);
        if (!(warm && warm_count >= self->warm_jerk))
            for (int j = 0; j < 7; j++) AT3(*S, i, 3, j) = 0.0;
        BYTE1(checked, i) = (unsigned char)(warm && warm_count >= self->warm_acceleration);
        failed += BYTE1(active, i) && !ok;
    }
    result = PyLong_FromSsize_t(failed);
done:
    f64_release(&h);
    bytes_release(&first);
    bytes_release(&active);
    bytes_release(&converged);
    bytes_release(&checked);
    return result;
}

/* record(T, twist, twist_stack, v_ex, w_ex, pose, apply, real, extrapolate, first,
 *        converged, position_error, rotation_error, echo) */
enum { R_T, R_TWIST, R_TWIST_STACK, R_V_EX, R_W_EX, R_POSITION_ERROR, R_ROTATION_ERROR,
       R_F64 };
enum { B_POSE, B_APPLY, B_REAL, B_EXTRAPOLATE, B_FIRST, B_CONVERGED, B_COUNT };

static PyObject *History_record(HistoryObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 14, "record") < 0) return NULL;
    Py_ssize_t n = self->n;
    Py_ssize_t s44[3] = {n, 4, 4}, s6[2] = {n, 6}, s36[3] = {n, 3, 6}, s3[2] = {n, 3}, s1[1] = {n};
    F64 a[R_F64];
    Bytes b[B_COUNT];
    Int64s echo;
    memset(a, 0, sizeof(a));
    memset(b, 0, sizeof(b));
    memset(&echo, 0, sizeof(echo));
    PyObject *result = NULL;
    static const char *const FNAMES[R_F64] = {"T", "twist", "twist_stack", "v_ex", "w_ex",
                                              "position_error", "rotation_error"};
    static const int FARG[R_F64] = {0, 1, 2, 3, 4, 11, 12};
    const Py_ssize_t *shapes[R_F64] = {s44, s6, s36, s3, s3, s1, s1};
    static const int NDIM[R_F64] = {3, 2, 3, 2, 2, 1, 1};
    static const char *const BNAMES[B_COUNT] = {"pose", "apply", "real", "extrapolate",
                                                "first", "converged"};
    static const int BARG[B_COUNT] = {5, 6, 7, 8, 9, 10};
    const int twisting = args[2] != Py_None, guessing = args[3] != Py_None;
    if (guessing != (args[4] != Py_None)) {
        PyErr_SetString(PyExc_ValueError, "record: v_ex and w_ex go together");
        return NULL;
    }
    for (int k = 0; k < R_F64; k++) {
        if ((k == R_TWIST_STACK && !twisting) || ((k == R_V_EX || k == R_W_EX) && !guessing))
            continue;
        if (f64_get(args[FARG[k]], &a[k], NDIM[k], shapes[k], 0, FNAMES[k]) < 0) goto done;
    }
    for (int k = 0; k < B_COUNT; k++)
        if (bytes_get(args[BARG[k]], &b[k], n, 0, BNAMES[k]) < 0) goto done;
    if (int64s_get(args[13], &echo, n, 0, "echo") < 0) goto done;
    int posing = 0;
    for (Py_ssize_t i = 0; i < n; i++) posing |= BYTE1(b[B_POSE], i) != 0;
    for (Py_ssize_t i = 0; i < n; i++)
        if (BYTE1(b[B_EXTRAPOLATE], i) && BYTE1(b[B_APPLY], i) && !guessing) {
            PyErr_SetString(PyExc_ValueError, "record: an extrapolated robot without v_ex, w_ex");
            goto done;
        }
    const double dt = self->dt;
    const Py_ssize_t *col = self->col;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!BYTE1(b[B_APPLY], i)) continue;
        double *row = row_of(&self->buffer, i);
        const int real = BYTE1(b[B_REAL], i) != 0, guess = BYTE1(b[B_EXTRAPOLATE], i) != 0;
        const int first = BYTE1(b[B_FIRST], i) != 0, ok = BYTE1(b[B_CONVERGED], i) != 0;
        double *T = row + col[C_T], *pose = row + col[C_POSE], *frozen = row + col[C_FROZEN];
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) T[4 * r + c] = AT3(a[R_T], i, r, c);
        /* The pose's history (every robot's while a pose motion runs, as the differences
         * are taken): the differences; a guess's own velocity and the frozen acceleration
         * (docs/fci-behaviour.md "What the sim does with a lost cycle"); at rest on the
         * opening command. The frozen acceleration follows the commands that arrived. */
        if (posing) {
            for (int k = 0; k < 6; k++) {
                double velocity = AT3(self->pose_stack, i, 0, k);
                double acceleration = AT3(self->pose_stack, i, 1, k);
                if (guess) {
                    velocity = k < 3 ? AT2(a[R_V_EX], i, k) : AT2(a[R_W_EX], i, k - 3);
                    acceleration = frozen[k];
                }
                if (first) velocity = acceleration = 0.0;
                pose[k] = velocity;
                pose[6 + k] = acceleration;
            }
            if (real)
                for (int k = 0; k < 6; k++) frozen[k] = pose[6 + k];
        }
        double *twist = row + col[C_TWIST], *dtwist = row + col[C_DTWIST];
        double *dtwist_frozen = row + col[C_DTWIST_FROZEN];
        if (twisting) {
            for (int k = 0; k < 6; k++) {
                twist[k] = AT2(a[R_TWIST], i, k);
                dtwist[k] = guess ? dtwist_frozen[k] : AT3(a[R_TWIST_STACK], i, 1, k);
            }
            if (real)
                for (int k = 0; k < 6; k++) dtwist_frozen[k] = dtwist[k];
        }
        /* The twist the state reports: a twist motion's own; a pose motion's in the base
         * frame, rotation R_c omega_body (record.py); its rate, zero on the opening command. */
        double reported[6];
        if (BYTE1(b[B_POSE], i)) {
            for (int k = 0; k < 3; k++) {
                const double R_row[3] = {T[4 * k], T[4 * k + 1], T[4 * k + 2]};
                reported[k] = pose[k];
                reported[3 + k] = 0.0 + dot3(R_row, pose + 3);
            }
        } else {
            for (int k = 0; k < 6; k++) reported[k] = twist[k];
        }
        double *was = row + col[C_REPORTED], *rate = row + col[C_DREPORTED];
        for (int k = 0; k < 6; k++) {
            rate[k] = first ? 0.0 : (reported[k] - was[k]) / dt;
            was[k] = reported[k];
        }
        /* The IK joint history: a usable solution is followed; rebased at rest on the
         * opening command and after a failed solve (the acceleration then needs two more
         * solutions, the jerk three: step.py WARM_*). */
        double *joint = row + col[C_JOINT], *warm = row + col[C_WARM];
        const int rebase = first || !ok;
        if (usable_solution(ok, AT1(a[R_POSITION_ERROR], i), AT1(a[R_ROTATION_ERROR], i),
                            self->usable_p, self->usable_r))
            for (int j = 0; j < 7; j++) joint[j] = AT3(self->joint_stack, i, 0, j);
        for (int j = 0; j < 7; j++) {
            joint[7 + j] = rebase ? 0.0 : AT3(self->joint_stack, i, 1, j);
            joint[14 + j] = rebase ? 0.0 : AT3(self->joint_stack, i, 2, j);
        }
        *warm = first ? self->warm_jerk : rebase ? 0.0 : *warm + 1.0;
        if (real) { /* the last command that actually arrived */
            INT64_AT(self->real_echo, i) = INT64_AT(echo, i);
            INT64_AT(self->run, i) = 0;
        }
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, R_F64);
    for (int k = 0; k < B_COUNT; k++) bytes_release(&b[k]);
    int64s_release(&echo);
    return result;
}

/* publish(pose, velocity) */
static PyObject *History_publish(HistoryObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "publish") < 0) return NULL;
    Py_ssize_t n = self->n;
    Bytes pose, velocity;
    memset(&velocity, 0, sizeof(velocity));
    if (bytes_get(args[0], &pose, n, 0, "pose") < 0) return NULL;
    if (bytes_get(args[1], &velocity, n, 0, "velocity") < 0) {
        bytes_release(&pose);
        return NULL;
    }
    const F64 *p = self->published;
    const Py_ssize_t *col = self->col;
    for (Py_ssize_t i = 0; i < n; i++) {
        const int posing = BYTE1(pose, i) != 0, twisting = BYTE1(velocity, i) != 0;
        if (!posing && !twisting) continue;
        const double *row = row_of(&self->buffer, i);
        /* the pose motion's commanded pose, or the pose a twist motion started from, as the
         * wire's column-major 4 x 4 (fci/frames.py to_wire) */
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) {
                double x = posing ? row[col[C_T] + 4 * r + c] : AT3(p[P_START_T], i, r, c);
                AT2(p[P_POSE_D], i, 4 * c + r) = x;
                AT2(p[P_POSE_C], i, 4 * c + r) = x;
            }
        for (int k = 0; k < 6; k++) {
            AT2(p[P_TWIST_D], i, k) = row[col[C_REPORTED] + k];
            AT2(p[P_TWIST_C], i, k) = row[col[C_REPORTED] + k];
            AT2(p[P_DTWIST_C], i, k) = row[col[C_DREPORTED] + k];
        }
        if (row[col[C_ELBOW_FLAG]] > 0.0) /* an elbow is streamed */
            for (int k = 0; k < 2; k++) {
                AT2(p[P_ELBOW_D], i, k) = row[col[C_ELBOW] + k];
                AT2(p[P_ELBOW_C], i, k) = row[col[C_ELBOW] + k];
            }
    }
    bytes_release(&pose);
    bytes_release(&velocity);
    Py_RETURN_NONE;
}

/* usable(converged, position_error, rotation_error, out, position_max, rotation_max) */
static PyObject *usable(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 6, "usable") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "converged");
    if (n < 0) return NULL;
    Py_ssize_t s1[1] = {n};
    Bytes converged, out;
    F64 p, r;
    memset(&out, 0, sizeof(out));
    memset(&p, 0, sizeof(p));
    memset(&r, 0, sizeof(r));
    PyObject *result = NULL;
    double bounds[2];
    static const char *const BOUNDS[2] = {"position_max", "rotation_max"};
    for (int k = 0; k < 2; k++) {
        bounds[k] = PyFloat_AsDouble(args[4 + k]);
        if (bounds[k] == -1.0 && PyErr_Occurred()) {
            PyErr_Format(PyExc_TypeError, "usable: %s must be a number", BOUNDS[k]);
            return NULL;
        }
    }
    if (bytes_get(args[0], &converged, n, 0, "converged") < 0) return NULL;
    if (f64_get(args[1], &p, 1, s1, 0, "position_error") < 0 ||
        f64_get(args[2], &r, 1, s1, 0, "rotation_error") < 0 ||
        bytes_get(args[3], &out, n, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++)
        BYTE1(out, i) = (unsigned char)usable_solution(BYTE1(converged, i) != 0, AT1(p, i),
                                                       AT1(r, i), bounds[0], bounds[1]);
    result = Py_NewRef(args[3]);
done:
    bytes_release(&converged);
    bytes_release(&out);
    f64_release(&p);
    f64_release(&r);
    return result;
}

static PyMethodDef HISTORY_METHODS[] = {
    {"pose_derivatives", (PyCFunction)(void (*)(void))History_pose_derivatives, METH_FASTCALL,
     "pose_derivatives(history, T): the pose's differences into pose_stack."},
    {"joint_side", (PyCFunction)(void (*)(void))History_joint_side, METH_FASTCALL,
     "joint_side(history, first, active, converged, checked) -> failed: the IK solution's "
     "differences into joint_stack."},
    {"record", (PyCFunction)(void (*)(void))History_record, METH_FASTCALL,
     "record(T, twist, twist_stack, v_ex, w_ex, pose, apply, real, extrapolate, first, "
     "converged, position_error, rotation_error, echo): a judged step into the history."},
    {"publish", (PyCFunction)(void (*)(void))History_publish, METH_FASTCALL,
     "publish(pose, velocity): the Cartesian fields the state reports of the history."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject HistoryType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.fci.cartesian._history.History",
    .tp_basicsize = sizeof(HistoryObject),
    .tp_dealloc = (destructor)History_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "History(buffer, real_echo, run, pose_stack, joint_stack, published, layout, "
              "constants): "
              "the Cartesian history's differences and record.",
    .tp_methods = HISTORY_METHODS,
    .tp_new = History_new,
};

static PyMethodDef METHODS[] = {
    METHOD(usable, "usable(converged, position_error, rotation_error, out, position_max, "
                   "rotation_max): the IK solutions the servo may follow."),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef _history_definition = {
    PyModuleDef_HEAD_INIT, "_history", "The Cartesian history's arithmetic.", -1, METHODS,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__history(void)
{
    if (PyType_Ready(&HistoryType) < 0) return NULL;
    PyObject *m = kernel_module(&_history_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "History", (PyObject *)&HistoryType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
