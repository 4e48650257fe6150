/* The Cartesian generators' per-cycle rules, each a fused copy of a numpy reference
 * (the IK itself is sim/_ik.c):
 *
 *   pose_step(T_c, T_prev, history, stack, q, joint, differences, h, limits) -> int
 *       fci/limits/cartesian.py pose_derivatives (with sim/kinematics.py
 *       relative_rotation_log) and joint_side, and the _quiet screen: 1 quiet, 0 not,
 *       -1 a rotation the kernel leaves to the reference (nothing written).
 *   twist_step(twist, twist_prev, dtwist_prev, stack, q, joint, differences, h, limits)
 *       -> bool: fci/cartesian.py _twist_derivatives, joint_side and the _quiet screen.
 *   homogeneous_quick(values, lo, hi) -> bool
 *       fci/frames.py is_homogeneous_wire's quick test (True: every pose passes).
 *   twist_target(T, twist, T_tw)
 *       fci/cartesian.py _twist_target: T_tw = T moved by the twist over one cycle (the
 *       translation the reference's bits, the rotation to rounding).
 *   record_pose(T_c, stack, T, history, acceleration_frozen, reported, dreported)
 *   record_twist(T_c, twist, stack, T, h_twist, dtwist, dtwist_frozen, reported,
 *                dreported)
 *       fci/cartesian.py _record and _record_reported for a cycle in which every robot
 *       recorded a command that arrived and none opened its motion (plain copies, the
 *       reported twist and its rate).
 *
 *   plain_cycle(pose, T_c, twist, history, T_tw, stack, joint, h, limits, F_T_EE, ik,
 *               rows_valid) -> bool
 *       fci/cartesian.py _cycle for a plain cycle, whole: the target, the IK
 *       (native/_ik_core.h, as sim/_ik.c), the step above and, where nothing is left to
 *       judge, the record; history_columns() -> dict: the history row's layout it uses.
 *
 * Elementwise chains (the translations, every backward difference, the joint side)
 * follow the reference's order of operations and are built without fused multiply-adds
 * (setup.py): the reference's bits. The twist target's rotation (exp(omega dt) @ R: 3x3
 * products, which numpy hands to BLAS) agrees with the reference to rounding. Reductions
 * (the rotation's trace and norm, the IK's products and its 6x6 solve) may differ from
 * numpy's in the last bits, so every comparison that uses one is a screen with a margin:
 * a pass means the reference passes too, anything near an edge is left to the
 * reference's exact rows. tests/fci/test_native_cartesian.py holds each kernel to its
 * reference, and plain_cycle to the general cycle bit for bit. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_ik_core.h"
#include "_rotation.h"

/* Squared norms (reductions) pass the quiet screen only this far inside their limits:
 * the reference's einsum may round a sum of three squares differently by a few ulp. */
#define SCREEN_MARGIN 1e-12

/* ---- derivatives, the joint side and the quiet screen ---------------------------------- */

/* joint_side over one arm: [dq, ddq, dddq] of q against joint's [q, dq, ddq] rows,
 * each (x - previous) / h as the reference's in-place subtract and divide. */
static void joint_differences(const F64 *q, const F64 *joint, const F64 *out, Py_ssize_t i,
                              double h)
{
    for (int j = 0; j < 7; j++) {
        double dq = (AT2(*q, i, j) - AT3(*joint, i, 0, j)) / h;
        double ddq = (dq - AT3(*joint, i, 1, j)) / h;
        AT3(*out, i, 0, j) = dq;
        AT3(*out, i, 1, j) = ddq;
        AT3(*out, i, 2, j) = (ddq - AT3(*joint, i, 2, j)) / h;
    }
}

/* _quiet for one arm: the six squared norms of stack's [v, omega, a, alpha, jerk, zeta]
 * within their squared limits (by SCREEN_MARGIN: a reduction) and the joint side's
 * |ddq|, |dddq| within theirs (exact: no reduction). NaN fails. */
static int arm_quiet(const F64 *stack, const F64 *differences, const F64 *limits, Py_ssize_t i)
{
    for (int k = 0; k < 6; k++) {
        int row = k / 2, col = 3 * (k % 2);
        double s = 0.0;
        for (int c = 0; c < 3; c++) {
            double x = AT3(*stack, i, row, col + c);
            s += x * x;
        }
        double limit = AT1(*limits, k);
        if (!(s <= limit - limit * SCREEN_MARGIN)) return 0;
    }
    for (int k = 0; k < 14; k++) {
        double x = fabs(AT3(*differences, i, 1 + k / 7, k % 7));
        if (!(x <= AT1(*limits, 6 + k))) return 0;
    }
    return 1;
}

/* relative_rotation_log(R_prev, R_c) of one arm, when its angle is below pi / 2 (the
 * reference's screened branches); returns 0 (nothing written) otherwise. */
static int rotation_velocity(const F64 *T_prev, const F64 *T_c, Py_ssize_t i, double vee[3])
{
    /* vee(M - M^T) of M = R_prev^T R_c, in the reference's contraction order */
    static const int A[3][2] = {{1, 2}, {0, 2}, {0, 1}};
    static const double SIGN[3] = {-1.0, 1.0, -1.0}; /* -eps of the first (a, b) */
    double two_cos = 0.0;
    for (int m = 0; m < 3; m++) {
        int p = A[m][0], r = A[m][1];
        double s = 0.0;
        for (int k = 0; k < 3; k++) {
            s += (SIGN[m] * AT3(*T_prev, i, k, p)) * AT3(*T_c, i, k, r);
            s += (-SIGN[m] * AT3(*T_prev, i, k, r)) * AT3(*T_c, i, k, p);
        }
        vee[m] = s;
    }
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++) two_cos += AT3(*T_prev, i, k, c) * AT3(*T_c, i, k, c);
    two_cos -= 1.0;
    double two_sin = sqrt(vee[0] * vee[0] + vee[1] * vee[1] + vee[2] * vee[2]);
    if (!(two_cos > 0.0) || isnan(two_sin)) return 0; /* at or past pi / 2, or NaN */
    /* angle / (2 sin angle), or its limit 1/2 where the rotation does not turn */
    double ratio = two_sin > 1e-12 ? atan2(two_sin, two_cos) / two_sin : 0.5;
    for (int k = 0; k < 3; k++) vee[k] *= ratio;
    return 1;
}

/* pose_derivatives over one arm: stack = [v | omega], [a | alpha], [jerk | zeta] of T_c
 * against T_prev and history (omega: its rotation_velocity), each (x - previous) / h. */
static void pose_derivatives_arm(const F64 *T_c, const F64 *T_prev, const F64 *history,
                                 const F64 *stack, Py_ssize_t i, const double omega[3],
                                 double h)
{
    double v[6], acc[6];
    for (int k = 0; k < 3; k++) {
        v[k] = AT3(*T_c, i, k, 3) - AT3(*T_prev, i, k, 3);
        v[3 + k] = omega[k];
    }
    for (int k = 0; k < 6; k++) {
        v[k] /= h;
        acc[k] = (v[k] - AT3(*history, i, 0, k)) / h;
        AT3(*stack, i, 0, k) = v[k];
        AT3(*stack, i, 1, k) = acc[k];
        AT3(*stack, i, 2, k) = (acc[k] - AT3(*history, i, 1, k)) / h;
    }
}

/* _twist_derivatives over one arm: stack = [twist, dtwist, ddtwist]. */
static void twist_derivatives_arm(const F64 *twist, const F64 *twist_prev,
                                  const F64 *dtwist_prev, const F64 *stack, Py_ssize_t i,
                                  double h)
{
    for (int k = 0; k < 6; k++) {
        double v = AT2(*twist, i, k);
        double dv = (v - AT2(*twist_prev, i, k)) / h;
        AT3(*stack, i, 0, k) = v;
        AT3(*stack, i, 1, k) = dv;
        AT3(*stack, i, 2, k) = (dv - AT2(*dtwist_prev, i, k)) / h;
    }
}

/* pose_step(T_c, T_prev, history, stack, q, joint, differences, h, limits) -> int
 *
 * pose_derivatives(T_c, T_prev, history, 1, out=stack), joint_side(q, joint[:, 0],
 * joint[:, 1], joint[:, 2], 1, out=differences) and _quiet(stack, differences[:, 1:]):
 * returns 1 (quiet) or 0. Returns -1, having written nothing, where some arm's relative
 * rotation is at or past pi / 2 (or NaN): the reference's other branches. */
static PyObject *pose_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { T_C, T_PREV, HISTORY, STACK, Q, JOINT, DIFF, LIMITS, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double *omega = NULL;
    if (check_nargs(nargs, 9, "pose_step") < 0) return NULL;
    double h = PyFloat_AsDouble(args[7]);
    if (PyErr_Occurred()) return NULL;
    Py_ssize_t n = leading(args[0], "T_c");
    if (n < 0) return NULL;
    Py_ssize_t s44[3] = {n, 4, 4}, s26[3] = {n, 2, 6}, s36[3] = {n, 3, 6}, s7[2] = {n, 7};
    Py_ssize_t s37[3] = {n, 3, 7}, s20[1] = {20};
    if (f64_get(args[0], &a[T_C], 3, s44, 0, "T_c") < 0 ||
        f64_get(args[1], &a[T_PREV], 3, s44, 0, "T_prev") < 0 ||
        f64_get(args[2], &a[HISTORY], 3, s26, 0, "history") < 0 ||
        f64_get(args[3], &a[STACK], 3, s36, 1, "stack") < 0 ||
        f64_get(args[4], &a[Q], 2, s7, 0, "q") < 0 ||
        f64_get(args[5], &a[JOINT], 3, s37, 0, "joint") < 0 ||
        f64_get(args[6], &a[DIFF], 3, s37, 1, "differences") < 0 ||
        f64_get(args[8], &a[LIMITS], 1, s20, 0, "limits") < 0)
        goto done;
    /* Every rotation first: the kernel writes nothing unless it handles every arm. */
    omega = PyMem_Malloc((size_t)(n > 0 ? n : 1) * 3 * sizeof(double));
    if (!omega) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!rotation_velocity(&a[T_PREV], &a[T_C], i, &omega[3 * i])) {
            result = PyLong_FromLong(-1);
            goto done;
        }
    }
    int quiet = 1;
    for (Py_ssize_t i = 0; i < n; i++) {
        pose_derivatives_arm(&a[T_C], &a[T_PREV], &a[HISTORY], &a[STACK], i, &omega[3 * i], h);
        joint_differences(&a[Q], &a[JOINT], &a[DIFF], i, h);
        quiet = quiet && arm_quiet(&a[STACK], &a[DIFF], &a[LIMITS], i);
    }
    result = PyLong_FromLong(quiet);
done:
    PyMem_Free(omega);
    f64_release_all(a, COUNT);
    return result;
}

/* twist_step(twist, twist_prev, dtwist_prev, stack, q, joint, differences, h, limits)
 *     -> bool
 *
 * _twist_derivatives (stack = [twist, dtwist, ddtwist]), joint_side into differences
 * and _quiet(stack, differences[:, 1:]), as pose_step. */
static PyObject *twist_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { TWIST, TWIST_PREV, DTWIST_PREV, STACK, Q, JOINT, DIFF, LIMITS, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    if (check_nargs(nargs, 9, "twist_step") < 0) return NULL;
    double h = PyFloat_AsDouble(args[7]);
    if (PyErr_Occurred()) return NULL;
    Py_ssize_t n = leading(args[0], "twist");
    if (n < 0) return NULL;
    Py_ssize_t s6[2] = {n, 6}, s36[3] = {n, 3, 6}, s7[2] = {n, 7}, s37[3] = {n, 3, 7};
    Py_ssize_t s20[1] = {20};
    if (f64_get(args[0], &a[TWIST], 2, s6, 0, "twist") < 0 ||
        f64_get(args[1], &a[TWIST_PREV], 2, s6, 0, "twist_prev") < 0 ||
        f64_get(args[2], &a[DTWIST_PREV], 2, s6, 0, "dtwist_prev") < 0 ||
        f64_get(args[3], &a[STACK], 3, s36, 1, "stack") < 0 ||
        f64_get(args[4], &a[Q], 2, s7, 0, "q") < 0 ||
        f64_get(args[5], &a[JOINT], 3, s37, 0, "joint") < 0 ||
        f64_get(args[6], &a[DIFF], 3, s37, 1, "differences") < 0 ||
        f64_get(args[8], &a[LIMITS], 1, s20, 0, "limits") < 0)
        goto done;
    int quiet = 1;
    for (Py_ssize_t i = 0; i < n; i++) {
        twist_derivatives_arm(&a[TWIST], &a[TWIST_PREV], &a[DTWIST_PREV], &a[STACK], i, h);
        joint_differences(&a[Q], &a[JOINT], &a[DIFF], i, h);
        quiet = quiet && arm_quiet(&a[STACK], &a[DIFF], &a[LIMITS], i);
    }
    result = PyBool_FromLong(quiet);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* ---- the wire pose's screen ------------------------------------------------------------ */

/* homogeneous_quick(values, lo, hi) -> bool
 *
 * is_homogeneous_wire's quick test on (n, 16) column-major wire poses: every value
 * finite, the bottom row (slots 3, 7, 11, 15) exactly [0, 0, 0, 1] and every row's and
 * column's squared norm of the rotation block strictly inside (lo, hi), a band half the
 * tolerance wide (so far from rounding). False: the exact test decides. */
static PyObject *homogeneous_quick(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    F64 values;
    memset(&values, 0, sizeof(values));
    if (check_nargs(nargs, 3, "homogeneous_quick") < 0) return NULL;
    double lo = PyFloat_AsDouble(args[1]), hi = PyFloat_AsDouble(args[2]);
    if (PyErr_Occurred()) return NULL;
    Py_ssize_t shape[2] = {-1, 16};
    if (f64_get(args[0], &values, 2, shape, 0, "values") < 0) return NULL;
    int pass = 1;
    for (Py_ssize_t i = 0; pass && i < values.shape[0]; i++) {
        double v[16];
        for (int k = 0; k < 16; k++) {
            v[k] = AT2(values, i, k);
            pass = pass && isfinite(v[k]);
        }
        pass = pass && v[3] == 0.0 && v[7] == 0.0 && v[11] == 0.0 && v[15] == 1.0;
        for (int r = 0; r < 3 && pass; r++) {
            double row = 0.0, col = 0.0; /* slot 4 c + r holds R[r][c] */
            for (int c = 0; c < 3; c++) {
                row += v[4 * c + r] * v[4 * c + r];
                col += v[4 * r + c] * v[4 * r + c];
            }
            pass = row > lo && row < hi && col > lo && col < hi;
        }
    }
    f64_release(&values);
    return PyBool_FromLong(pass);
}

/* The cycle's time step (fci/cartesian.py _DT). */
#define CYCLE_DT KERNEL_DT

/* The reported twist's rate, then the twist: dreported = (twist - reported) / dt. */
static inline void report(const F64 *reported, const F64 *dreported, Py_ssize_t i,
                          const double twist[6])
{
    for (int k = 0; k < 6; k++) {
        AT2(*dreported, i, k) = (twist[k] - AT2(*reported, i, k)) / CYCLE_DT;
        AT2(*reported, i, k) = twist[k];
    }
}

/* sim/kinematics.py rotation_exp of rv = omega dt (Rodrigues; the series below 1e-8 rad)
 * composed on the left of the row-major 3x3 R: out = exp(rv) @ R. */
static void turn_left(const double rv[3], const double *R, double *out)
{
    double angle = sqrt((rv[0] * rv[0] + rv[1] * rv[1]) + rv[2] * rv[2]);
    double a2 = angle * angle;
    if (angle < 1e-8)
        rotate_left(rv, 1.0 - a2 / 6.0, 0.5 - a2 / 24.0, R, out);
    else
        rotate_left(rv, sin(angle) / angle, (1.0 - cos(angle)) / a2, R, out);
}

/* twist_target over one arm (below). */
static void twist_target_arm(const F64 *T, const F64 *twist, const F64 *out, Py_ssize_t i)
{
    double R[9], rv[3], turned[9];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) AT3(*out, i, r, c) = AT3(*T, i, r, c);
    int turning = 0;
    for (int k = 0; k < 3; k++) {
        AT3(*out, i, k, 3) += AT2(*twist, i, k) * CYCLE_DT;
        rv[k] = AT2(*twist, i, 3 + k) * CYCLE_DT;
        if (AT2(*twist, i, 3 + k) != 0.0) turning = 1;
    }
    if (!turning) return;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) R[3 * r + c] = AT3(*T, i, r, c);
    turn_left(rv, R, turned);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) AT3(*out, i, r, c) = turned[3 * r + c];
}

/* twist_target(T, twist, T_tw): _twist_target. T_tw = T, its translation +=
 * twist[:3] * dt (numpy's order: the product first: the reference's bits) and, where
 * the twist turns, its rotation exp(twist[3:] dt) @ R: the 3x3 products (numpy's go
 * through BLAS) agree with the reference's to rounding. A twist without rotation keeps R
 * exactly, as the reference does. */
static PyObject *twist_target(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 3, "twist_target") < 0) return NULL;
    enum { T, TW, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t n = leading(args[0], "T");
    if (n < 0) goto done;
    Py_ssize_t s44[3] = {n, 4, 4}, s6[2] = {n, 6};
    if (f64_get(args[0], &a[T], 3, s44, 0, "T") < 0) goto done;
    if (f64_get(args[1], &a[TW], 2, s6, 0, "twist") < 0) goto done;
    if (f64_get(args[2], &a[OUT], 3, s44, 1, "T_tw") < 0) goto done;
    for (Py_ssize_t i = 0; i < n; i++) twist_target_arm(&a[T], &a[TW], &a[OUT], i);
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* record_pose over one arm (below). */
static void record_pose_arm(const F64 *T_c, const F64 *stack, const F64 *T, const F64 *hist,
                            const F64 *frozen, const F64 *reported, const F64 *dreported,
                            Py_ssize_t i)
{
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) AT3(*T, i, r, c) = AT3(*T_c, i, r, c);
    for (int k = 0; k < 6; k++) {
        AT3(*hist, i, 0, k) = AT3(*stack, i, 0, k);
        AT3(*hist, i, 1, k) = AT3(*stack, i, 1, k);
        AT2(*frozen, i, k) = AT3(*stack, i, 1, k);
    }
    double twist[6];
    for (int k = 0; k < 3; k++) {
        twist[k] = AT3(*hist, i, 0, k);
        twist[3 + k] = (AT3(*T, i, k, 0) * AT3(*hist, i, 0, 3) +
                        AT3(*T, i, k, 2) * AT3(*hist, i, 0, 5)) +
                       AT3(*T, i, k, 1) * AT3(*hist, i, 0, 4);
    }
    report(reported, dreported, i, twist);
}

/* record_pose(T_c, stack, T, history, acceleration_frozen, reported, dreported)
 *
 * T = T_c; history = stack[:, :2] ([v | omega], [a | alpha]); acceleration_frozen =
 * [a | alpha]; the reported twist is [v | R omega] with R = T's rotation (the body
 * rate turned into the base frame; numpy's einsum sums the three products as
 * (0 + 2) + 1, and so does this), and its rate against the last one. */
static PyObject *record_pose(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 7, "record_pose") < 0) return NULL;
    enum { TC, STACK, T, HIST, FROZEN, REP, DREP, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t n = leading(args[0], "T_c");
    if (n < 0) goto done;
    Py_ssize_t s44[3] = {n, 4, 4}, s36[3] = {n, 3, 6}, s26[3] = {n, 2, 6}, s6[2] = {n, 6};
    if (f64_get(args[0], &a[TC], 3, s44, 0, "T_c") < 0) goto done;
    if (f64_get(args[1], &a[STACK], 3, s36, 0, "stack") < 0) goto done;
    if (f64_get(args[2], &a[T], 3, s44, 1, "T") < 0) goto done;
    if (f64_get(args[3], &a[HIST], 3, s26, 1, "history") < 0) goto done;
    if (f64_get(args[4], &a[FROZEN], 2, s6, 1, "acceleration_frozen") < 0) goto done;
    if (f64_get(args[5], &a[REP], 2, s6, 1, "reported") < 0) goto done;
    if (f64_get(args[6], &a[DREP], 2, s6, 1, "dreported") < 0) goto done;
    for (Py_ssize_t i = 0; i < n; i++)
        record_pose_arm(&a[TC], &a[STACK], &a[T], &a[HIST], &a[FROZEN], &a[REP], &a[DREP], i);
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* record_twist over one arm (below). */
static void record_twist_arm(const F64 *T_c, const F64 *tw, const F64 *stack, const F64 *T,
                             const F64 *h_twist, const F64 *dtwist, const F64 *frozen,
                             const F64 *reported, const F64 *dreported, Py_ssize_t i)
{
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) AT3(*T, i, r, c) = AT3(*T_c, i, r, c);
    double twist[6];
    for (int k = 0; k < 6; k++) {
        twist[k] = AT2(*tw, i, k);
        AT2(*h_twist, i, k) = twist[k];
        AT2(*dtwist, i, k) = AT3(*stack, i, 1, k);
        AT2(*frozen, i, k) = AT3(*stack, i, 1, k);
    }
    report(reported, dreported, i, twist);
}

/* record_twist(T_c, twist, stack, T, h_twist, dtwist, dtwist_frozen, reported, dreported)
 *
 * T = T_c (the twist-integrated target); the twist and its rate (stack[:, 1]), frozen
 * for extrapolation; the reported twist is the twist itself. */
static PyObject *record_twist(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 9, "record_twist") < 0) return NULL;
    enum { TC, TW, STACK, T, HTW, DTW, FROZEN, REP, DREP, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t n = leading(args[0], "T_c");
    if (n < 0) goto done;
    Py_ssize_t s44[3] = {n, 4, 4}, s36[3] = {n, 3, 6}, s6[2] = {n, 6};
    if (f64_get(args[0], &a[TC], 3, s44, 0, "T_c") < 0) goto done;
    if (f64_get(args[1], &a[TW], 2, s6, 0, "twist") < 0) goto done;
    if (f64_get(args[2], &a[STACK], 3, s36, 0, "stack") < 0) goto done;
    if (f64_get(args[3], &a[T], 3, s44, 1, "T") < 0) goto done;
    if (f64_get(args[4], &a[HTW], 2, s6, 1, "h_twist") < 0) goto done;
    if (f64_get(args[5], &a[DTW], 2, s6, 1, "dtwist") < 0) goto done;
    if (f64_get(args[6], &a[FROZEN], 2, s6, 1, "dtwist_frozen") < 0) goto done;
    if (f64_get(args[7], &a[REP], 2, s6, 1, "reported") < 0) goto done;
    if (f64_get(args[8], &a[DREP], 2, s6, 1, "dreported") < 0) goto done;
    for (Py_ssize_t i = 0; i < n; i++)
        record_twist_arm(&a[TC], &a[TW], &a[STACK], &a[T], &a[HTW], &a[DTW], &a[FROZEN], &a[REP],
                         &a[DREP], i);
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    return result;
}


/* ---- the plain cycle ------------------------------------------------------------------- */

/* The columns of one robot's history row (fci/cartesian_reference.py CartesianHistory);
 * history_columns() hands them to Python, which uses plain_cycle only where they agree. */
enum {
    COL_T = 0,                    /* (4, 4) */
    COL_HISTORY = 16,             /* (2, 6): [v | omega], [a | alpha] */
    COL_ACCELERATION_FROZEN = 28, /* (6,) */
    COL_TWIST = 34,               /* (6,) */
    COL_DTWIST = 40,              /* (6,) */
    COL_DTWIST_FROZEN = 46,       /* (6,) */
    COL_REPORTED = 52,            /* (6,) */
    COL_DREPORTED = 58,           /* (6,) */
    COL_JOINT = 70,               /* (3, 7): [q_ik, dq_ik, ddq_ik] */
    COL_IK_WARM = 91,             /* () */
    COL_WIDTH = 92
};

static PyObject *history_columns(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return Py_BuildValue("{s:i,s:i,s:i,s:i,s:i,s:i,s:i,s:i,s:i,s:i,s:i}", "T", COL_T,
                         "history", COL_HISTORY, "acceleration_frozen",
                         COL_ACCELERATION_FROZEN, "twist", COL_TWIST, "dtwist", COL_DTWIST,
                         "dtwist_frozen", COL_DTWIST_FROZEN, "reported", COL_REPORTED,
                         "dreported", COL_DREPORTED, "joint", COL_JOINT, "ik_warm",
                         COL_IK_WARM, "WIDTH", COL_WIDTH);
}

/* fci/cartesian.py _WARM_JERK: converged IK samples since a rebase before the joint
 * side's jerk (30) is judged; below it _joint_checked zeroes the jerk (not plain). */
#define WARM_JERK 2.0

/* A view of columns [col, col + d1 * d2) of the (n, WIDTH) history as an (n, d1, d2)
 * array (d2 = 0: (n, d1)); it borrows the history's buffer (nothing to release). */
static F64 columns(const F64 *history, int col, int d1, int d2)
{
    F64 v;
    memset(&v, 0, sizeof(v));
    Py_ssize_t step = history->strides[1];
    v.data = history->data + col * step;
    v.kind = 'd';
    v.shape[0] = history->shape[0];
    v.strides[0] = history->strides[0];
    v.shape[1] = d1;
    if (d2) {
        v.ndim = 3;
        v.strides[1] = d2 * step;
        v.shape[2] = d2;
        v.strides[2] = step;
    } else {
        v.ndim = 2;
        v.strides[1] = step;
    }
    return v;
}

/* A view of joint's (n, 4, 7) rows [from, from + count) as (n, count, 7), or row
 * ``from`` as (n, 7) (count = 0). */
static F64 joint_rows(const F64 *joint, int from, int count)
{
    F64 v = *joint;
    memset(&v.view, 0, sizeof(v.view));
    v.data = joint->data + from * joint->strides[1];
    if (count) {
        v.shape[1] = count;
    } else {
        v.ndim = 2;
        v.shape[1] = 7;
        v.strides[1] = joint->strides[2];
    }
    return v;
}

/* plain_cycle(pose, T_c, twist, history, T_tw, stack, joint, h, limits, F_T_EE, ik,
 *             rows_valid) -> bool
 *
 * fci/cartesian.py _cycle for the plain cycle of a world whose robots all run one
 * generator (``pose``: O_T_EE_c, T_c the commands; else O_dP_EE_c, twist the commands
 * and T_tw the twist target's scratch), every robot's command arrived, none opens its
 * motion and no elbow is streamed: the IK target (_twist_target), the IK (ik_solve from
 * the history's q_ik into joint[:, 0]), the derivatives, the joint side and the quiet
 * screen (pose_step / twist_step into stack and joint[:, 1:]) — then, where every solve
 * converged, every joint history is warm and the screen is quiet (so _check judges
 * nothing), the record: _record_plain, the joint history [q, dq, ddq] and ik_warm + 1.
 * Returns True when it recorded; False having written only scratch (stack, joint, T_tw,
 * the IK's cache and MjData): the caller runs the general path, which recomputes it all.
 * ``ik``: (cached_q, qpos, site_pos, site_mat, axes, anchors, base, errors, converged,
 * damping2, tol2, max_step, max_iterations, kinematics), sim/kinematics.py
 * ArmKinematics.native_solve; ``history``: the (n, WIDTH) buffer of CartesianReference. */
static PyObject *plain_cycle(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { T_C, TWIST, HIST, T_TW, STACK, JOINT, LIMITS, F_EE, COUNT };
    F64 a[COUNT];
    Mask every;
    IkSolver solver;
    memset(a, 0, sizeof(a));
    memset(&every, 0, sizeof(every));
    memset(&solver, 0, sizeof(solver));
    PyObject *result = NULL;
    if (check_nargs(nargs, 12, "plain_cycle") < 0) return NULL;
    int pose = PyObject_IsTrue(args[0]);
    double h = PyFloat_AsDouble(args[7]);
    int rows_valid = PyObject_IsTrue(args[11]);
    if (pose < 0 || rows_valid < 0 || PyErr_Occurred()) return NULL;
    Py_ssize_t n = leading(args[3], "history");
    if (n < 0) return NULL;
    Py_ssize_t s44[3] = {n, 4, 4}, s6[2] = {n, 6}, sH[2] = {n, COL_WIDTH}, s36[3] = {n, 3, 6};
    Py_ssize_t s47[3] = {n, 4, 7}, s20[1] = {20};
    if ((pose ? f64_get(args[1], &a[T_C], 3, s44, 0, "T_c")
              : f64_get(args[2], &a[TWIST], 2, s6, 0, "twist")) < 0 ||
        f64_get(args[3], &a[HIST], 2, sH, 1, "history") < 0 ||
        (!pose && f64_get(args[4], &a[T_TW], 3, s44, 1, "T_tw") < 0) ||
        f64_get(args[5], &a[STACK], 3, s36, 1, "stack") < 0 ||
        f64_get(args[6], &a[JOINT], 3, s47, 1, "joint") < 0 ||
        f64_get(args[8], &a[LIMITS], 1, s20, 0, "limits") < 0 ||
        (args[9] != Py_None && f64_get(args[9], &a[F_EE], 3, s44, 0, "F_T_EE") < 0) ||
        ik_solver_get(args[10], n, &solver) < 0)
        goto done;
    const F64 *hist = &a[HIST];
    F64 T_prev = columns(hist, COL_T, 4, 4), history = columns(hist, COL_HISTORY, 2, 6);
    F64 frozen = columns(hist, COL_ACCELERATION_FROZEN, 6, 0);
    F64 twist_prev = columns(hist, COL_TWIST, 6, 0), dtwist = columns(hist, COL_DTWIST, 6, 0);
    F64 dtwist_frozen = columns(hist, COL_DTWIST_FROZEN, 6, 0);
    F64 reported = columns(hist, COL_REPORTED, 6, 0);
    F64 dreported = columns(hist, COL_DREPORTED, 6, 0);
    F64 joint_history = columns(hist, COL_JOINT, 3, 7), q_ik = columns(hist, COL_JOINT, 7, 0);
    F64 q = joint_rows(&a[JOINT], 0, 0), differences = joint_rows(&a[JOINT], 1, 3);
    F64 solution = joint_rows(&a[JOINT], 0, 3);
    /* the IK target: the commanded pose, or the twist's integral */
    const F64 *target = &a[T_C];
    if (!pose) {
        for (Py_ssize_t i = 0; i < n; i++) twist_target_arm(&T_prev, &a[TWIST], &a[T_TW], i);
        target = &a[T_TW];
    }
    IkProblem problem = ik_problem(&solver, &q_ik, &q, target, &a[F_EE], NULL, &every);
    if (ik_solve_core(&problem, &solver.kin, n, rows_valid) < 0) goto done;
    /* The derivatives, the joint side and the screen; plain only if every arm is. */
    int plain = 1;
    for (Py_ssize_t i = 0; i < n && plain; i++) {
        double w[3];
        if (pose) {
            if (!rotation_velocity(&T_prev, &a[T_C], i, w)) {
                plain = 0; /* a rotation the kernel leaves to the reference */
                break;
            }
            pose_derivatives_arm(&a[T_C], &T_prev, &history, &a[STACK], i, w, h);
        } else {
            twist_derivatives_arm(&a[TWIST], &twist_prev, &dtwist, &a[STACK], i, h);
        }
        joint_differences(&q, &joint_history, &differences, i, h);
        int converged = solver.converged.data[i * solver.converged.stride] != 0;
        plain = converged && AT2(*hist, i, COL_IK_WARM) >= WARM_JERK &&
                arm_quiet(&a[STACK], &differences, &a[LIMITS], i);
    }
    if (!plain) {
        result = Py_NewRef(Py_False);
        goto done;
    }
    /* The record: _record_plain, _record_joint_side's plain copy, ik_warm + 1. */
    for (Py_ssize_t i = 0; i < n; i++) {
        if (pose)
            record_pose_arm(&a[T_C], &a[STACK], &T_prev, &history, &frozen, &reported,
                            &dreported, i);
        else
            record_twist_arm(&a[T_TW], &a[TWIST], &a[STACK], &T_prev, &twist_prev, &dtwist,
                             &dtwist_frozen, &reported, &dreported, i);
        for (int r = 0; r < 3; r++)
            for (int j = 0; j < 7; j++) AT3(joint_history, i, r, j) = AT3(solution, i, r, j);
        AT2(*hist, i, COL_IK_WARM) += 1.0;
    }
    result = Py_NewRef(Py_True);
done:
    f64_release_all(a, COUNT);
    ik_solver_release(&solver);
    return result;
}

static PyMethodDef METHODS[] = {
    {"pose_step", (PyCFunction)(void (*)(void))pose_step, METH_FASTCALL,
     "pose_step(T_c, T_prev, history, stack, q, joint, differences, h, limits) -> int: "
     "pose_derivatives, joint_side and _quiet (1 quiet, 0 not, -1 left to the reference)."},
    {"twist_step", (PyCFunction)(void (*)(void))twist_step, METH_FASTCALL,
     "twist_step(twist, twist_prev, dtwist_prev, stack, q, joint, differences, h, limits) "
     "-> bool: _twist_derivatives, joint_side and _quiet."},
    {"homogeneous_quick", (PyCFunction)(void (*)(void))homogeneous_quick, METH_FASTCALL,
     "homogeneous_quick(values, lo, hi) -> bool: is_homogeneous_wire's quick test."},
    {"twist_target", (PyCFunction)(void (*)(void))twist_target, METH_FASTCALL,
     "twist_target(T, twist, T_tw): _twist_target, T moved by the twist over one cycle."},
    {"record_pose", (PyCFunction)(void (*)(void))record_pose, METH_FASTCALL,
     "record_pose(T_c, stack, T, history, acceleration_frozen, reported, dreported): "
     "_record of a pose cycle every robot recorded."},
    {"record_twist", (PyCFunction)(void (*)(void))record_twist, METH_FASTCALL,
     "record_twist(T_c, twist, stack, T, h_twist, dtwist, dtwist_frozen, reported, "
     "dreported): _record of a twist cycle every robot recorded."},
    {"plain_cycle", (PyCFunction)(void (*)(void))plain_cycle, METH_FASTCALL,
     "plain_cycle(pose, T_c, twist, history, T_tw, stack, joint, h, limits, F_T_EE, ik, "
     "rows_valid) -> bool: _cycle's plain cycle in one call (True: recorded)."},
    {"history_columns", history_columns, METH_NOARGS,
     "history_columns() -> dict: the history row's columns plain_cycle reads and writes."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_cartesian_rules,
              "The Cartesian generators' per-cycle rules (fused copies of numpy reference code).")
