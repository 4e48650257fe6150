/* libfranka's client-side filter rules, which the env's in-process client runs every cycle
 * and envs/client_filters.py / envs/cartesian_filters.py expose with libfranka's checks:
 * their only text (issue 38: one text per rule). envs/client_kernel.py loads the module
 * (native.require) and hands over its constants (configure): fci/tables.py's cycle,
 * libfranka's rate_limiting.h kNormEps and kFactorCartesianRotationPoseInterface, and
 * sim/rotations.py's thresholds, so none is repeated here. Every rule takes (n, ...)
 * arrays, ``out`` last:
 *
 *   lowpass(x, x_ref, gain, out)                               franka::lowpassFilter
 *   limit_velocities(v_c, v_last, a_last, upper, lower, a_max, j_max, out)
 *   limit_positions(q_c, q_last, v_last, a_last, upper, lower, a_max, j_max, out)
 *   JointClient(positions, limited, q_d, dq_d, ddq_d, gain, constants, positional, shift,
 *               a_max, j_max, out).cycle(target, first)   lowpass (+ band, limiter): one call
 *   limit_torques(tau_c, tau_last, d_max, out)                 franka::limitRate (joints)
 *   limit_twist(twist_c, twist_last, dtwist_last, limits, out)
 *   limit_pose(T_c, T_last, twist_last, dtwist_last, limits, out)   (Cartesian)
 *   cartesian_lowpass(T_c, T_ref, gain, out)                   franka::cartesianLowpassFilter
 *   reference_pose(O_T_EE_c, out)                              the state's pose, as read
 *
 * (libfranka 0.21 src/lowpass_filter.cpp, src/rate_limiting.cpp; docs/limits.md §6.)
 * Built without fused multiply-adds (setup.py); 3-vector dot products sum as
 * (x0 y0 + x2 y2) + x1 y1, the order the deleted numpy text summed them in, so the
 * env's command streams kept their bits when it went (the pose rules' trigonometry is
 * libm's).
 *
 * Reference arrays may be the wire state's float32 fields (widened exactly). Inputs are
 * assumed finite: the env validates its action once, the state is the controller's own,
 * and the public functions raise libfranka's errors before calling in. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_envelope.h"
#include "_kernel.h"
#include "_rotation.h"

/* The constants configure() receives: fci/tables.py DELTA_T, libfranka's kNormEps and
 * kFactorCartesianRotationPoseInterface (envs/cartesian_filters.py), and
 * sim/rotations.py's NEAR_PI, TURNING_ABOVE, SERIES_BELOW and SLERP_LINEAR (into
 * _rotation.h's ROTATION). */
static double DT, NORM_EPS, ROTATION_POSE_FACTOR;
static int CONFIGURED = 0;

/* configure(dt, norm_eps, rotation_pose_factor, near_pi, turning_above, series_below,
 * slerp_linear) */
static PyObject *configure(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    double v[7];
    if (positive_constants(args, nargs, 7, v) < 0) return NULL;
    DT = v[0];
    NORM_EPS = v[1];
    ROTATION_POSE_FACTOR = v[2];
    rotation_configure(v + 3);
    CONFIGURED = 1;
    Py_RETURN_NONE;
}


/* ---- the low-pass filter -------------------------------------------------------------- */

/* franka::lowpassFilter of one value. */
static ALWAYS_INLINE double lowpass_value(double x, double x_ref, double gain)
{
    return gain * x + (1.0 - gain) * x_ref;
}

/* lowpass(x, x_ref, gain, out): (n, k) each (x_ref float32 or float64; gain one per
 * element, a broadcast view for one gain): gain * x + (1 - gain) * x_ref. */
static void lowpass_rows(const F64 *a, Py_ssize_t n)
{
    enum { X, REF, GAIN, RESULT };
    for (Py_ssize_t i = 0; i < n; i++)
        for (Py_ssize_t j = 0; j < a[X].shape[1]; j++)
            put2(&a[RESULT], i, j,
                 lowpass_value(AT2(a[X], i, j), num2(&a[REF], i, j), AT2(a[GAIN], i, j)));
}
KERNEL(lowpass, 0, ARRAY(F64_IN, "x", 2, ROWS, COLS), ARRAY(NUM_IN, "x_ref", 2, ROWS, COLS),
       ARRAY(F64_IN, "gain", 2, ROWS, COLS), ARRAY(OUT, "out", 2, ROWS, COLS))

/* ---- joints and torques -------------------------------------------------------------- */

/* franka::limitRate's joint law for one joint: the command c (a position with ``positions``,
 * its velocity then (c - q_last) / dt) against the last velocity and acceleration, inside
 * the band [lower, upper], at most A and J. */
static ALWAYS_INLINE double limit_joint(double c, double q_last, double v_last, double a_last,
                                        double upper, double lower, double a_max, double j_max,
                                        int positions)
{
    const double dt = DT;
    double v_c = positions ? (c - q_last) / dt : c;
    double jerk = (((v_c - v_last) / dt) - a_last) / dt;
    double acc = a_last + np_maximum(np_minimum(jerk, j_max), -j_max) * dt;
    double ratio = j_max / a_max;
    double safe_max = np_minimum(ratio * (upper - v_last), a_max);
    double safe_min = np_maximum(ratio * (lower - v_last), -a_max);
    double v = v_last + np_maximum(np_minimum(acc, safe_max), safe_min) * dt;
    return positions ? q_last + v * dt : v;
}

/* limit_velocities / limit_positions: (n, 7) commands, history, bounds, A and J (a
 * broadcast view for one A and J per joint). ``positions``: q_last leads the arguments. */
static void joint_rows(const F64 *a, Py_ssize_t n, int positions)
{
    enum { C, QLAST };
    enum { VLAST, ALAST, UPPER, LOWER, AMAX, JMAX, RESULT };
    const F64 *r = a + (positions ? 2 : 1); /* v_last onwards */
    for (Py_ssize_t i = 0; i < n; i++)
        for (int j = 0; j < 7; j++) {
            double q_last = positions ? num2(&a[QLAST], i, j) : 0.0;
            put2(&r[RESULT], i, j,
                 limit_joint(AT2(a[C], i, j), q_last, num2(&r[VLAST], i, j),
                             num2(&r[ALAST], i, j), AT2(r[UPPER], i, j), AT2(r[LOWER], i, j),
                             AT2(r[AMAX], i, j), AT2(r[JMAX], i, j), positions));
        }
}

#define JOINT_HISTORY_AND_LIMITS                                                          \
    ARRAY(NUM_IN, "v_last", 2, ROWS, 7), ARRAY(NUM_IN, "a_last", 2, ROWS, 7),             \
        ARRAY(F64_IN, "upper", 2, ROWS, 7), ARRAY(F64_IN, "lower", 2, ROWS, 7),           \
        ARRAY(F64_IN, "a_max", 2, ROWS, 7), ARRAY(F64_IN, "j_max", 2, ROWS, 7),           \
        ARRAY(OUT, "out", 2, ROWS, 7)

static void limit_velocities_rows(const F64 *a, Py_ssize_t n)
{
    joint_rows(a, n, 0);
}
KERNEL(limit_velocities, 1, ARRAY(F64_IN, "command", 2, ROWS, 7), JOINT_HISTORY_AND_LIMITS)

static void limit_positions_rows(const F64 *a, Py_ssize_t n)
{
    joint_rows(a, n, 1);
}
KERNEL(limit_positions, 1, ARRAY(F64_IN, "command", 2, ROWS, 7),
       ARRAY(NUM_IN, "q_last", 2, ROWS, 7), JOINT_HISTORY_AND_LIMITS)

/* One cycle of the env client's joint
 * position (``positions`` true) or joint velocity command (envs/commands.py
 * CommandGenerator), one call: libfranka's low-pass of the target
 * against its reference (q_d, or dq_d for a velocity; a position motion's first command,
 * where ``first``, against the target itself), then its limiter inside the velocity band
 * at q_d (native/_envelope.h, the robot's law, with the client's ``shift`` for its
 * tolerance) where ``limited`` (``limit_rate``; the low-pass alone otherwise). (n, 7) arrays (q_d, dq_d, ddq_d float32 or float64; gain, a_max and j_max
 * broadcast views for one value), ``first`` an (n,) bool or None, ``constants`` and
 * ``positional`` RobotTable.joint_constants. The same rows as lowpass, envelope_halves
 * and limit_positions / limit_velocities one after the other: the same bits. */
/* The arrays of a joint cycle, in this order: target, q_d, dq_d, ddq_d, gain, constants,
 * a_max, j_max, out. */
enum { JC_TARGET, JC_Q_D, JC_DQ_D, JC_DDQ_D, JC_GAIN, JC_CONSTANTS, JC_A_MAX, JC_J_MAX, JC_OUT,
       JC_COUNT };

/* The cycle's rows over borrowed arrays (JointClient.cycle's loop). */
static void joint_cycle_rows(F64 *a, const Bytes *first, Py_ssize_t n, int positions,
                             int limited, int pos, double shift)
{
    const int firsts = first->data != NULL;
    for (Py_ssize_t i = 0; i < n; i++) {
        const int own = positions && firsts && BYTE1(*first, i);
        for (int j = 0; j < 7; j++) {
            const double target = AT2(a[JC_TARGET], i, j), q_d = num2(&a[JC_Q_D], i, j);
            const double dq_d = num2(&a[JC_DQ_D], i, j);
            const double ref = own ? target : positions ? q_d : dq_d;
            const double x = lowpass_value(target, ref, AT2(a[JC_GAIN], i, j));
            if (!limited) {
                AT2(a[JC_OUT], i, j) = x;
                continue;
            }
            double upper, lower;
            envelope(&a[JC_CONSTANTS], j, q_d, pos, shift, &upper, &lower);
            AT2(a[JC_OUT], i, j) =
                limit_joint(x, q_d, dq_d, num2(&a[JC_DDQ_D], i, j), upper, lower,
                            AT2(a[JC_A_MAX], i, j), AT2(a[JC_J_MAX], i, j), positions);
        }
    }
}

/* JointClient(positions, limited, q_d, dq_d, ddq_d, gain, constants, positional, shift,
 *             a_max, j_max, out).cycle(target, first) -> out
 * The joint cycle above as a plan: the state's fields, the filter's settings and the output
 * held, a cycle hands over the target and the first-command flags (an (n,) bool, or None). */
typedef struct {
    PyObject_HEAD
    Py_ssize_t n;
    int positions, limited, pos;
    double shift;
    PyObject *out;
    F64 a[JC_COUNT];
} JointClientObject;

static void JointClient_dealloc(JointClientObject *self)
{
    f64_release_all(self->a, JC_COUNT);
    Py_XDECREF(self->out);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *JointClient_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "JointClient() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 12, "JointClient") < 0) return NULL;
    if (!CONFIGURED) {
        PyErr_SetString(PyExc_RuntimeError, "JointClient: configure(...) first");
        return NULL;
    }
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    Py_ssize_t n = leading(v[11], "out");
    if (n < 0) return NULL;
    JointClientObject *self = (JointClientObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    self->positions = PyObject_IsTrue(v[0]);
    self->limited = PyObject_IsTrue(v[1]);
    double positional = PyFloat_AsDouble(v[7]);
    self->shift = PyFloat_AsDouble(v[8]);
    Py_ssize_t s7[2] = {n, 7}, sc[2] = {N_CONSTANTS, 7};
    F64 *a = self->a;
    if (self->positions < 0 || self->limited < 0 || PyErr_Occurred() ||
        num_get(v[2], &a[JC_Q_D], 2, s7, 0, "q_d") < 0 ||
        num_get(v[3], &a[JC_DQ_D], 2, s7, 0, "dq_d") < 0 ||
        num_get(v[4], &a[JC_DDQ_D], 2, s7, 0, "ddq_d") < 0 ||
        f64_get(v[5], &a[JC_GAIN], 2, s7, 0, "gain") < 0 ||
        f64_get(v[6], &a[JC_CONSTANTS], 2, sc, 0, "constants") < 0 ||
        f64_get(v[9], &a[JC_A_MAX], 2, s7, 0, "a_max") < 0 ||
        f64_get(v[10], &a[JC_J_MAX], 2, s7, 0, "j_max") < 0 ||
        f64_get(v[11], &a[JC_OUT], 2, s7, 1, "out") < 0) {
        Py_DECREF(self);
        return NULL;
    }
    self->pos = positional != 0.0;
    self->out = Py_NewRef(v[11]);
    return (PyObject *)self;
}

static PyObject *JointClient_cycle(JointClientObject *self, PyObject *const *args,
                                   Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "cycle") < 0) return NULL;
    Py_ssize_t s7[2] = {self->n, 7};
    Bytes first;
    if (f64_get(args[0], &self->a[JC_TARGET], 2, s7, 0, "target") < 0) return NULL;
    if (bytes_or_none_get(args[1], &first, self->n, 0, "first") < 0) {
        f64_release(&self->a[JC_TARGET]);
        return NULL;
    }
    joint_cycle_rows(self->a, &first, self->n, self->positions, self->limited, self->pos,
                     self->shift);
    f64_release(&self->a[JC_TARGET]);
    bytes_release(&first);
    return Py_NewRef(self->out);
}

static PyMethodDef JOINT_CLIENT_METHODS[] = {
    {"cycle", (PyCFunction)(void (*)(void))JointClient_cycle, METH_FASTCALL,
     "cycle(target, first) -> out: one cycle of the joint command (joint_cycle's rows)."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject JointClientType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.envs._client_filters.JointClient",
    .tp_basicsize = sizeof(JointClientObject),
    .tp_dealloc = (destructor)JointClient_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "JointClient(positions, limited, q_d, dq_d, ddq_d, gain, constants, positional, "
              "shift, a_max, j_max, out): a joint position (or velocity) command's low-pass "
              "(then, limited, its band and limiter), all but the target held.",
    .tp_methods = JOINT_CLIENT_METHODS,
    .tp_new = JointClient_new,
};

/* limit_torques(tau_c, tau_last, d_max, out): (n, 7) each (d_max a broadcast view for
 * one rate). */
static void limit_torques_rows(const F64 *a, Py_ssize_t n)
{
    enum { C, LAST, DMAX, RESULT };
    const double dt = DT;
    for (Py_ssize_t i = 0; i < n; i++)
        for (int j = 0; j < 7; j++) {
            double last = num2(&a[LAST], i, j), d_max = AT2(a[DMAX], i, j);
            double rate = (AT2(a[C], i, j) - last) / dt;
            put2(&a[RESULT], i, j, last + np_maximum(np_minimum(rate, d_max), -d_max) * dt);
        }
}
KERNEL(limit_torques, 1, ARRAY(F64_IN, "tau_c", 2, ROWS, 7),
       ARRAY(NUM_IN, "tau_last", 2, ROWS, 7), ARRAY(F64_IN, "d_max", 2, ROWS, 7),
       ARRAY(OUT, "out", 2, ROWS, 7))

/* ---- the twist ----------------------------------------------------------------------- */

/* libfranka's 3-vector limiter (limitRate's twist overload) on one half of a twist. */
static void limit_norm(const double *v_c, const double *v_last, const double *a_last,
                       double v_max, double a_max, double j_max, double *out)
{
    const double dt = DT;
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

/* One twist through the limiter, both halves. */
static void twist_limited(const double *x, const double *last, const double *dlast,
                          const double limits[6], double *out)
{
    for (int h = 0; h < 2; h++)
        limit_norm(x + 3 * h, last + 3 * h, dlast + 3 * h, limits[3 * h], limits[3 * h + 1],
                   limits[3 * h + 2], out + 3 * h);
}

/* limit_twist(twist_c, twist_last, dtwist_last, limits, out): (n, 6) each; a robot's
 * limits are (v, a, j, v_rot, a_rot, j_rot) (a broadcast view for one set). */
static void limit_twist_rows(const F64 *a, Py_ssize_t n)
{
    enum { C, LAST, DLAST, LIMITS, RESULT };
    for (Py_ssize_t i = 0; i < n; i++) {
        double x[6], last[6], dlast[6], limits[6], limited[6];
        for (int k = 0; k < 6; k++) {
            x[k] = AT2(a[C], i, k);
            last[k] = num2(&a[LAST], i, k);
            dlast[k] = num2(&a[DLAST], i, k);
            limits[k] = AT2(a[LIMITS], i, k);
        }
        twist_limited(x, last, dlast, limits, limited);
        for (int k = 0; k < 6; k++) put2(&a[RESULT], i, k, limited[k]);
    }
}

#define TWIST_HISTORY_AND_LIMITS                                                          \
    ARRAY(NUM_IN, "twist_last", 2, ROWS, 6), ARRAY(NUM_IN, "dtwist_last", 2, ROWS, 6),    \
        ARRAY(F64_IN, "limits", 2, ROWS, 6)

KERNEL(limit_twist, 1, ARRAY(F64_IN, "twist_c", 2, ROWS, 6), TWIST_HISTORY_AND_LIMITS,
       ARRAY(OUT, "out", 2, ROWS, 6))

/* ---- poses ----------------------------------------------------------------------------- */

/* The (n, 4, 4) pose argument i as 16 row-major values. */
static void pose_at(const F64 *T, Py_ssize_t i, double *out)
{
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) out[4 * r + c] = AT3(*T, i, r, c);
}

static void pose_put(const F64 *T, Py_ssize_t i, const double *v)
{
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) AT3(*T, i, r, c) = v[4 * r + c];
}

static void rotation_of(const double *T, double *R)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) R[3 * r + c] = T[4 * r + c];
}

/* cartesian_lowpass(T_c, T_ref, gain, out): (n, 4, 4) poses, (n,) gains (a broadcast view
 * for one gain). */
static void cartesian_lowpass_rows(const F64 *a, Py_ssize_t n)
{
    enum { C, REF, GAIN, RESULT };
    for (Py_ssize_t i = 0; i < n; i++) {
        const double gain = AT1(a[GAIN], i);
        double T_c[16], T_ref[16], R_c[9], R_ref[9], q_c[4], q_ref[4], q[4], R[9], F[16];
        pose_at(&a[C], i, T_c);
        pose_at(&a[REF], i, T_ref);
        rotation_of(T_c, R_c);
        rotation_of(T_ref, R_ref);
        rotation_to_quaternion(R_ref, q_ref);
        rotation_to_quaternion(R_c, q_c);
        quaternion_slerp(q_ref, q_c, gain, q);
        double norm = sqrt(dot4(q, q));
        for (int k = 0; k < 4; k++) q[k] /= norm;
        quaternion_to_rotation(q, R);
        memcpy(F, T_c, sizeof(F));
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) F[4 * r + c] = R[3 * r + c];
            F[4 * r + 3] = gain * T_c[4 * r + 3] + (1.0 - gain) * T_ref[4 * r + 3];
        }
        pose_put(&a[RESULT], i, F);
    }
}
KERNEL(cartesian_lowpass, 1, ARRAY(F64_IN, "T_c", 3, ROWS, 4, 4),
       ARRAY(F64_IN, "T_ref", 3, ROWS, 4, 4), ARRAY(F64_IN, "gain", 1, ROWS),
       ARRAY(OUT, "out", 3, ROWS, 4, 4))

/* limit_pose(T_c, T_last, twist_last, dtwist_last, limits, out): (n, 4, 4) poses, (n, 6)
 * twists and limits (the rotational ones unscaled: kFactorCartesianRotationPoseInterface
 * is applied here). */
static void limit_pose_rows(const F64 *a, Py_ssize_t n)
{
    enum { C, LAST, TW, DTW, LIMITS, RESULT };
    const double dt = DT;
    for (Py_ssize_t i = 0; i < n; i++) {
        double T_c[16], T_last[16], R_c[9], R_last[9], R_diff[9], twist[6], last[6], dlast[6];
        double limited[6], T[16], limits[6];
        for (int k = 0; k < 3; k++) limits[k] = AT2(a[LIMITS], i, k);
        for (int k = 3; k < 6; k++) limits[k] = ROTATION_POSE_FACTOR * AT2(a[LIMITS], i, k);
        pose_at(&a[C], i, T_c);
        pose_at(&a[LAST], i, T_last);
        rotation_of(T_c, R_c);
        rotation_of(T_last, R_last);
        for (int k = 0; k < 6; k++) {
            last[k] = num2(&a[TW], i, k);
            dlast[k] = num2(&a[DTW], i, k);
        }
        for (int k = 0; k < 3; k++) twist[k] = (T_c[4 * k + 3] - T_last[4 * k + 3]) / dt;
        mat3_mul(R_c, R_last, 1, R_diff);
        rotation_log(R_diff, twist + 3);
        for (int k = 3; k < 6; k++) twist[k] /= dt;
        twist_limited(twist, last, dlast, limits, limited);
        /* integrated over one cycle: exp(w dt) on the left where |w| > kNormEps */
        const double *w = limited + 3;
        double R[9];
        if (sqrt(dot3(w, w)) > NORM_EPS) {
            double rv[3] = {w[0] * dt, w[1] * dt, w[2] * dt};
            exp_left(rv, R_last, R);
        } else {
            memcpy(R, R_last, sizeof(R));
        }
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) T[4 * r + c] = R[3 * r + c];
            T[4 * r + 3] = T_last[4 * r + 3] + limited[r] * dt;
        }
        T[12] = T[13] = T[14] = 0.0;
        T[15] = 1.0;
        pose_put(&a[RESULT], i, T);
    }
}
KERNEL(limit_pose, 1, ARRAY(F64_IN, "T_c", 3, ROWS, 4, 4),
       ARRAY(F64_IN, "T_last", 3, ROWS, 4, 4), TWIST_HISTORY_AND_LIMITS,
       ARRAY(OUT, "out", 3, ROWS, 4, 4))

/* reference_pose(O_T_EE_c, out): (n, 16) column-major (float32 or float64) to (n, 4, 4)
 * row-major, each rotation its nearest rotation. */
static void reference_pose_rows(const F64 *a, Py_ssize_t n)
{
    enum { WIRE, RESULT };
    for (Py_ssize_t i = 0; i < n; i++) {
        double T[16], R[9];
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) T[4 * r + c] = num2(&a[WIRE], i, 4 * c + r);
        rotation_of(T, R);
        nearest_rotation(R);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) T[4 * r + c] = R[3 * r + c];
        pose_put(&a[RESULT], i, T);
    }
}
KERNEL(reference_pose, 0, ARRAY(NUM_IN, "O_T_EE_c", 2, ROWS, 16),
       ARRAY(OUT, "out", 3, ROWS, 4, 4))

static PyMethodDef METHODS[] = {
    METHOD(configure, "configure(dt, norm_eps, rotation_pose_factor, near_pi, turning_above, "
                      "series_below, slerp_linear): the rules' constants."),
    METHOD(lowpass, "lowpass(x, x_ref, gain, out): franka::lowpassFilter."),
    METHOD(limit_velocities, "limit_velocities(v_c, v_last, a_last, upper, lower, a_max, "
                             "j_max, out): franka::limitRate for joint velocities."),
    METHOD(limit_positions, "limit_positions(q_c, q_last, v_last, a_last, upper, lower, "
                            "a_max, j_max, out): franka::limitRate for joint positions."),
    METHOD(limit_torques, "limit_torques(tau_c, tau_last, d_max, out): franka::limitRate "
                          "for torques."),
    METHOD(limit_twist, "limit_twist(twist_c, twist_last, dtwist_last, limits, out): "
                        "franka::limitRate for O_dP_EE_c."),
    METHOD(cartesian_lowpass, "cartesian_lowpass(T_c, T_ref, gain, out): "
                              "franka::cartesianLowpassFilter."),
    METHOD(limit_pose, "limit_pose(T_c, T_last, twist_last, dtwist_last, limits, out): "
                       "franka::limitRate for O_T_EE_c."),
    METHOD(reference_pose, "reference_pose(O_T_EE_c, out): the state's pose as the client "
                           "reads it."),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef _client_filters_definition = {
    PyModuleDef_HEAD_INIT, "_client_filters",
    "libfranka's client filter rules, which the env's client runs every cycle.", -1, METHODS,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__client_filters(void)
{
    if (PyType_Ready(&JointClientType) < 0) return NULL;
    PyObject *m = kernel_module(&_client_filters_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "JointClient", (PyObject *)&JointClientType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
