/* Cartesian kernels of the 1 kHz cycle, each a fused copy of a numpy reference:
 *
 *   ik_begin(q_init, q, cached_q, qpos, elbow, active) -> bool
 *       the start of sim/kinematics.py ArmKinematics.solve: q = q_init, the held elbows
 *       set, q written to the private MjData's qpos; whether q moved off cached_q.
 *   ik_step(q, qpos, cached_q, site_pos, site_mat, axes, anchors, base, target, F_T_EE,
 *           elbow, active, errors, converged, damping2, tol2, max_step, last) -> int
 *       one pass of ArmKinematics.solve's loop on MjData's rows as mj_kinematics left
 *       them (_evaluate, the error, the convergence test and _update's damped step);
 *       returns how many arms stepped (then qpos holds the new q: run mj_kinematics).
 *   pose_step(T_c, T_prev, history, stack, q, joint, differences, h, limits) -> int
 *       fci/limits/cartesian.py pose_derivatives (with sim/kinematics.py
 *       relative_rotation_log) and joint_side, and the _quiet screen: 1 quiet, 0 not,
 *       -1 a rotation the kernel leaves to the reference (nothing written).
 *   twist_step(twist, twist_prev, dtwist_prev, stack, q, joint, differences, h, limits)
 *       -> bool: fci/cartesian.py _twist_derivatives, joint_side and the _quiet screen.
 *   homogeneous_quick(values, lo, hi) -> bool
 *       fci/frames.py is_homogeneous_wire's quick test (True: every pose passes).
 *   twist_target(T, twist, T_tw) -> bool
 *       fci/cartesian.py _twist_target's translation: T_tw = T moved by the twist's
 *       translation over one cycle; True when some twist turns (its rotation is then
 *       composed in numpy).
 *   record_pose(T_c, stack, T, history, acceleration_frozen, reported, dreported)
 *   record_twist(T_c, twist, stack, T, h_twist, dtwist, dtwist_frozen, reported,
 *                dreported)
 *       fci/cartesian.py _record and _record_reported for a cycle in which every robot
 *       recorded a command that arrived and none opened its motion (plain copies, the
 *       reported twist and its rate).
 *
 * Elementwise chains (the translations, every backward difference, the joint side)
 * follow the reference's order of operations and are built without fused multiply-adds
 * (setup.py): the reference's bits. Reductions (the rotation's trace and norm, the IK's
 * products and its 6x6 solve) may differ from numpy's in the last bits, so every
 * comparison that uses one is a screen with a margin: a pass means the reference passes
 * too, anything near an edge is left to the reference's exact rows.
 * tests/test_native_cartesian.py holds each kernel to its reference. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"

/* Squared norms (reductions) pass the quiet screen only this far inside their limits:
 * the reference's einsum may round a sum of three squares differently by a few ulp. */
#define SCREEN_MARGIN 1e-12

/* sim/kinematics.py ELBOW_JOINT: joint 3, the FR3's redundancy angle. */
#define ELBOW_JOINT 2

/* A bool (n,) argument (numpy bool: one byte each), or None (data NULL). */
typedef struct {
    Py_buffer view;
    const char *data;
    Py_ssize_t stride;
} Mask;

static int mask_get(PyObject *obj, Mask *m, Py_ssize_t n, int writable, const char *name)
{
    memset(m, 0, sizeof(*m));
    if (obj == Py_None) return 0;
    int flags = PyBUF_RECORDS_RO | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &m->view, flags) < 0) {
        PyErr_Format(PyExc_ValueError, "%s: expected a%s bool array", name,
                     writable ? " writable" : "");
        return -1;
    }
    const char *f = m->view.format;
    if (f && (*f == '<' || *f == '=' || *f == '@' || *f == '|')) f++;
    if (m->view.ndim != 1 || m->view.itemsize != 1 || !f || strcmp(f, "?") != 0 ||
        m->view.shape[0] != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected a bool array of shape (%zd,)", name, n);
        PyBuffer_Release(&m->view);
        m->view.obj = NULL;
        return -1;
    }
    m->data = (const char *)m->view.buf;
    m->stride = m->view.strides ? m->view.strides[0] : 1;
    return 0;
}

static inline int mask_at(const Mask *m, Py_ssize_t i, int otherwise)
{
    return m->data ? m->data[i * m->stride] != 0 : otherwise;
}

static void mask_release(Mask *m)
{
    if (m->view.obj) PyBuffer_Release(&m->view);
    m->view.obj = NULL;
}

/* A kernel's argument count. */
static int check_nargs(Py_ssize_t nargs, Py_ssize_t expected, const char *name)
{
    if (nargs == expected) return 0;
    PyErr_Format(PyExc_TypeError, "%s() takes %zd arguments (%zd given)", name, expected, nargs);
    return -1;
}

/* The length of the first axis of the array ``obj`` (the others' shapes follow it). */
static Py_ssize_t leading(PyObject *obj, const char *name)
{
    Py_buffer view;
    if (PyObject_GetBuffer(obj, &view, PyBUF_RECORDS_RO) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected an array", name);
        return -1;
    }
    Py_ssize_t n = view.ndim >= 1 ? view.shape[0] : -1;
    PyBuffer_Release(&view);
    if (n < 0) PyErr_Format(PyExc_ValueError, "%s: expected an array of 1 or more axes", name);
    return n;
}

/* ---- the IK -------------------------------------------------------------------------- */

/* ik_begin(q_init, q, cached_q, qpos, elbow, active) -> bool
 *
 * ArmKinematics.solve's start: q = q_init, then joint 3 = elbow where the arm is active
 * and its elbow finite (held); qpos = q. True when q differs from cached_q anywhere (or
 * is NaN): MjData's rows are not at q and mj_kinematics must run. cached_q = q. */
static PyObject *ik_begin(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { Q_INIT, Q, CACHED, QPOS, COUNT };
    F64 a[COUNT];
    Mask active;
    memset(a, 0, sizeof(a));
    memset(&active, 0, sizeof(active));
    PyObject *result = NULL;
    if (check_nargs(nargs, 6, "ik_begin") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "q_init");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, s1[1] = {n};
    F64 elbow;
    memset(&elbow, 0, sizeof(elbow));
    if (f64_get(args[0], &a[Q_INIT], 2, s7, 0, "q_init") < 0 ||
        f64_get(args[1], &a[Q], 2, s7, 1, "q") < 0 ||
        f64_get(args[2], &a[CACHED], 2, s7, 1, "cached_q") < 0 ||
        f64_get(args[3], &a[QPOS], 2, s7, 1, "qpos") < 0 ||
        (args[4] != Py_None && f64_get(args[4], &elbow, 1, s1, 0, "elbow") < 0) ||
        mask_get(args[5], &active, n, 0, "active") < 0)
        goto done;
    int moved = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) AT2(a[Q], i, j) = AT2(a[Q_INIT], i, j);
        if (elbow.data && mask_at(&active, i, 1) && isfinite(AT1(elbow, i)))
            AT2(a[Q], i, ELBOW_JOINT) = AT1(elbow, i);
        for (int j = 0; j < 7; j++) {
            double v = AT2(a[Q], i, j);
            if (!(v == AT2(a[CACHED], i, j))) moved = 1;
            AT2(a[CACHED], i, j) = v;
            AT2(a[QPOS], i, j) = v;
        }
    }
    result = PyBool_FromLong(moved);
done:
    f64_release_all(a, COUNT);
    f64_release(&elbow);
    mask_release(&active);
    return result;
}

/* One arm's evaluation (ArmKinematics._evaluate) from MjData's rows: the EE position in
 * the base frame p, its rotation R and the point the Jacobian's lever arms end at. */
typedef struct {
    double p[3], R[3][3], p_world[3];
} Pose;

static void arm_pose(const F64 *site_pos, const F64 *site_mat, const F64 *base, const F64 *F,
                     Py_ssize_t i, Pose *out)
{
    double Rs[3][3], ps[3];
    for (int r = 0; r < 3; r++) {
        ps[r] = AT2(*site_pos, i, r);
        for (int c = 0; c < 3; c++) Rs[r][c] = AT3(*site_mat, i, r, c);
    }
    if (F) { /* the EE frame F_T_EE on the flange: p + R_site F_p, R_site F_R */
        for (int r = 0; r < 3; r++) {
            double offset = 0.0;
            for (int k = 0; k < 3; k++) offset += Rs[r][k] * AT3(*F, i, k, 3);
            out->p_world[r] = ps[r] + offset;
            for (int c = 0; c < 3; c++) {
                double s = 0.0;
                for (int k = 0; k < 3; k++) s += Rs[r][k] * AT3(*F, i, k, c);
                out->R[r][c] = s;
            }
        }
    } else { /* the flange itself */
        for (int r = 0; r < 3; r++) {
            out->p_world[r] = ps[r];
            for (int c = 0; c < 3; c++) out->R[r][c] = Rs[r][c];
        }
    }
    for (int r = 0; r < 3; r++) out->p[r] = out->p_world[r] - AT2(*base, i, r);
}

/* The pose error [p_t - p | vee((E - E^T) / 2) of E = R_t R^T] (solve's e_pos, e_rot). */
static void pose_error(const F64 *target, Py_ssize_t i, const Pose *pose, double e[6])
{
    double M[3][3]; /* R_t R^T */
    for (int a = 0; a < 3; a++) {
        e[a] = AT3(*target, i, a, 3) - pose->p[a];
        for (int b = 0; b < 3; b++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += AT3(*target, i, a, k) * pose->R[b][k];
            M[a][b] = s;
        }
    }
    e[3] = 0.5 * (M[2][1] - M[1][2]);
    e[4] = 0.5 * (M[0][2] - M[2][0]);
    e[5] = 0.5 * (M[1][0] - M[0][1]);
}

/* Solve the 6x6 system A x = b in place (Gaussian elimination, partial pivoting, as
 * LAPACK's gesv does); b becomes x. A singular matrix gives inf / NaN, as there. */
static void solve6(double A[6][6], double b[6])
{
    for (int c = 0; c < 6; c++) {
        int pivot = c;
        for (int r = c + 1; r < 6; r++)
            if (fabs(A[r][c]) > fabs(A[pivot][c])) pivot = r;
        if (pivot != c) {
            for (int k = 0; k < 6; k++) {
                double t = A[c][k];
                A[c][k] = A[pivot][k];
                A[pivot][k] = t;
            }
            double t = b[c];
            b[c] = b[pivot];
            b[pivot] = t;
        }
        for (int r = c + 1; r < 6; r++) {
            double f = A[r][c] / A[c][c];
            for (int k = c; k < 6; k++) A[r][k] -= f * A[c][k];
            b[r] -= f * b[c];
        }
    }
    for (int r = 5; r >= 0; r--) {
        double s = b[r];
        for (int k = r + 1; k < 6; k++) s -= A[r][k] * b[k];
        b[r] = s / A[r][r];
    }
}

/* One arm's damped Gauss-Newton step J^T (J J^T + lambda^2 I)^-1 e (_update), joint 3's
 * column zeroed where the elbow is held. */
static void damped_step(const F64 *axes, const F64 *anchors, Py_ssize_t i, const Pose *pose,
                        int fixed, const double e[6], double damping2, double step[7])
{
    double J[6][7];
    for (int j = 0; j < 7; j++) {
        double ax[3], lever[3];
        for (int k = 0; k < 3; k++) {
            ax[k] = AT3(*axes, i, j, k);
            lever[k] = pose->p_world[k] - AT3(*anchors, i, j, k);
        }
        /* linear: axis x (EE point - joint anchor); angular: the axis */
        J[0][j] = ax[1] * lever[2] - ax[2] * lever[1];
        J[1][j] = ax[2] * lever[0] - ax[0] * lever[2];
        J[2][j] = ax[0] * lever[1] - ax[1] * lever[0];
        for (int k = 0; k < 3; k++) J[3 + k][j] = ax[k];
    }
    if (fixed)
        for (int r = 0; r < 6; r++) J[r][ELBOW_JOINT] = 0.0;
    double A[6][6], x[6];
    for (int r = 0; r < 6; r++) {
        for (int c = 0; c < 6; c++) {
            double s = 0.0;
            for (int j = 0; j < 7; j++) s += J[r][j] * J[c][j];
            A[r][c] = s + (r == c ? damping2 : 0.0);
        }
        x[r] = e[r];
    }
    solve6(A, x);
    for (int j = 0; j < 7; j++) {
        double s = 0.0;
        for (int r = 0; r < 6; r++) s += J[r][j] * x[r];
        step[j] = s;
    }
}

/* ik_step(q, qpos, cached_q, site_pos, site_mat, axes, anchors, base, target, F_T_EE,
 *         elbow, active, errors, converged, damping2, tol2, max_step, last) -> int
 *
 * One pass of solve's loop, MjData's rows being at q: every arm's error (errors (2, n):
 * position and rotation error, as IkResult reports them) and verdict (converged (n,)
 * bool); then, unless every arm converged, no active arm is left or ``last``, the damped
 * step of the active unconverged arms (each capped at max_step per joint; the others
 * add zero, as the reference's masked step does), q += step, qpos = cached_q = q.
 * Returns the number of arms stepped. F_T_EE (n, 4, 4) or None (the flange); elbow (n,)
 * (joint 3 held where finite) or None; active (n,) bool or None (every arm). */
static PyObject *ik_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { Q, QPOS, CACHED, SITE_POS, SITE_MAT, AXES, ANCHORS, BASE, TARGET, ERRORS, COUNT };
    F64 a[COUNT], F, elbow;
    Mask active, converged;
    memset(a, 0, sizeof(a));
    memset(&F, 0, sizeof(F));
    memset(&elbow, 0, sizeof(elbow));
    memset(&active, 0, sizeof(active));
    memset(&converged, 0, sizeof(converged));
    PyObject *result = NULL;
    double *steps = NULL;
    if (check_nargs(nargs, 18, "ik_step") < 0) return NULL;
    double damping2 = PyFloat_AsDouble(args[14]), tol2 = PyFloat_AsDouble(args[15]);
    double max_step = PyFloat_AsDouble(args[16]);
    int last = PyObject_IsTrue(args[17]);
    if (PyErr_Occurred() || last < 0) return NULL;
    Py_ssize_t n = leading(args[0], "q");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, s3[2] = {n, 3}, s33[3] = {n, 3, 3}, s73[3] = {n, 7, 3};
    Py_ssize_t s44[3] = {n, 4, 4}, s1[1] = {n}, s2n[2] = {2, n};
    if (f64_get(args[0], &a[Q], 2, s7, 1, "q") < 0 ||
        f64_get(args[1], &a[QPOS], 2, s7, 1, "qpos") < 0 ||
        f64_get(args[2], &a[CACHED], 2, s7, 1, "cached_q") < 0 ||
        f64_get(args[3], &a[SITE_POS], 2, s3, 0, "site_pos") < 0 ||
        f64_get(args[4], &a[SITE_MAT], 3, s33, 0, "site_mat") < 0 ||
        f64_get(args[5], &a[AXES], 3, s73, 0, "axes") < 0 ||
        f64_get(args[6], &a[ANCHORS], 3, s73, 0, "anchors") < 0 ||
        f64_get(args[7], &a[BASE], 2, s3, 0, "base") < 0 ||
        f64_get(args[8], &a[TARGET], 3, s44, 0, "target") < 0 ||
        (args[9] != Py_None && f64_get(args[9], &F, 3, s44, 0, "F_T_EE") < 0) ||
        (args[10] != Py_None && f64_get(args[10], &elbow, 1, s1, 0, "elbow") < 0) ||
        mask_get(args[11], &active, n, 0, "active") < 0 ||
        f64_get(args[12], &a[ERRORS], 2, s2n, 1, "errors") < 0 ||
        mask_get(args[13], &converged, n, 1, "converged") < 0)
        goto done;
    if (!converged.data) {
        PyErr_SetString(PyExc_ValueError, "converged: expected a bool array, not None");
        goto done;
    }
    char *done_arm = (char *)converged.data;
    /* Every arm's error and verdict (solve: err2 <= tol2, both halves; NaN fails). */
    Py_ssize_t n_ok = 0, n_todo = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        Pose pose;
        double e[6];
        arm_pose(&a[SITE_POS], &a[SITE_MAT], &a[BASE], F.data ? &F : NULL, i, &pose);
        pose_error(&a[TARGET], i, &pose, e);
        double err2_p = 0.0, err2_r = 0.0;
        for (int k = 0; k < 3; k++) {
            err2_p += e[k] * e[k];
            err2_r += e[3 + k] * e[3 + k];
        }
        AT2(a[ERRORS], 0, i) = sqrt(err2_p);
        AT2(a[ERRORS], 1, i) = sqrt(err2_r);
        int ok_p = err2_p <= tol2, ok_r = err2_r <= tol2;
        n_ok += ok_p + ok_r;
        done_arm[i * converged.stride] = (char)(ok_p && ok_r);
        n_todo += mask_at(&active, i, 1) && !(ok_p && ok_r);
    }
    if (n_ok == 2 * n || last || n_todo == 0) {
        result = PyLong_FromLong(0);
        goto done;
    }
    /* The damped steps of the arms still to do; the others' are zero. */
    steps = PyMem_Calloc((size_t)n * 7, sizeof(double));
    if (!steps) {
        PyErr_NoMemory();
        goto done;
    }
    int any_big = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!mask_at(&active, i, 1) || done_arm[i * converged.stride]) continue;
        Pose pose;
        double e[6];
        arm_pose(&a[SITE_POS], &a[SITE_MAT], &a[BASE], F.data ? &F : NULL, i, &pose);
        pose_error(&a[TARGET], i, &pose, e);
        int fixed = elbow.data && isfinite(AT1(elbow, i));
        damped_step(&a[AXES], &a[ANCHORS], i, &pose, fixed, e, damping2, &steps[7 * i]);
        for (int j = 0; j < 7; j++) any_big |= fabs(steps[7 * i + j]) > max_step;
    }
    /* The cap (_update): where any joint of any arm would move more than max_step, every
     * arm's step is scaled by min(1, max_step / max(biggest, max_step)), NaN-propagating
     * as numpy's minimum / maximum are (a factor of exactly 1 changes nothing). */
    for (Py_ssize_t i = 0; any_big && i < n; i++) {
        double *step = &steps[7 * i];
        double biggest = fabs(step[0]);
        for (int j = 1; j < 7; j++) {
            double v = fabs(step[j]);
            if (isnan(v) || v > biggest) biggest = isnan(biggest) ? biggest : v;
        }
        double m = (isnan(biggest) || biggest >= max_step) ? biggest : max_step;
        double ratio = max_step / m;
        double factor = isnan(ratio) ? ratio : (1.0 <= ratio ? 1.0 : ratio);
        for (int j = 0; j < 7; j++) step[j] *= factor;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) {
            double v = AT2(a[Q], i, j) + steps[7 * i + j];
            AT2(a[Q], i, j) = v;
            AT2(a[QPOS], i, j) = v;
            AT2(a[CACHED], i, j) = v;
        }
    }
    result = PyLong_FromSsize_t(n_todo);
done:
    PyMem_Free(steps);
    f64_release_all(a, COUNT);
    f64_release(&F);
    f64_release(&elbow);
    mask_release(&active);
    mask_release(&converged);
    return result;
}

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
        double v[6], acc[6];
        for (int k = 0; k < 3; k++) {
            v[k] = AT3(a[T_C], i, k, 3) - AT3(a[T_PREV], i, k, 3);
            v[3 + k] = omega[3 * i + k];
        }
        for (int k = 0; k < 6; k++) {
            v[k] /= h;
            acc[k] = (v[k] - AT3(a[HISTORY], i, 0, k)) / h;
            AT3(a[STACK], i, 0, k) = v[k];
            AT3(a[STACK], i, 1, k) = acc[k];
            AT3(a[STACK], i, 2, k) = (acc[k] - AT3(a[HISTORY], i, 1, k)) / h;
        }
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
        for (int k = 0; k < 6; k++) {
            double v = AT2(a[TWIST], i, k);
            double dv = (v - AT2(a[TWIST_PREV], i, k)) / h;
            AT3(a[STACK], i, 0, k) = v;
            AT3(a[STACK], i, 1, k) = dv;
            AT3(a[STACK], i, 2, k) = (dv - AT2(a[DTWIST_PREV], i, k)) / h;
        }
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

/* twist_target(T, twist, T_tw) -> bool: T_tw = T, its translation += twist[:3] * dt
 * (numpy's order: the product first); whether any twist has a rotation. */
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
    int turning = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) AT3(a[OUT], i, r, c) = AT3(a[T], i, r, c);
        for (int k = 0; k < 3; k++) {
            AT3(a[OUT], i, k, 3) += AT2(a[TW], i, k) * CYCLE_DT;
            if (AT2(a[TW], i, 3 + k) != 0.0) turning = 1;
        }
    }
    result = PyBool_FromLong(turning);
done:
    f64_release_all(a, COUNT);
    return result;
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
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) AT3(a[T], i, r, c) = AT3(a[TC], i, r, c);
        for (int k = 0; k < 6; k++) {
            AT3(a[HIST], i, 0, k) = AT3(a[STACK], i, 0, k);
            AT3(a[HIST], i, 1, k) = AT3(a[STACK], i, 1, k);
            AT2(a[FROZEN], i, k) = AT3(a[STACK], i, 1, k);
        }
        double twist[6];
        for (int k = 0; k < 3; k++) {
            twist[k] = AT3(a[HIST], i, 0, k);
            twist[3 + k] = (AT3(a[T], i, k, 0) * AT3(a[HIST], i, 0, 3) +
                            AT3(a[T], i, k, 2) * AT3(a[HIST], i, 0, 5)) +
                           AT3(a[T], i, k, 1) * AT3(a[HIST], i, 0, 4);
        }
        report(&a[REP], &a[DREP], i, twist);
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    return result;
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
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++) AT3(a[T], i, r, c) = AT3(a[TC], i, r, c);
        double twist[6];
        for (int k = 0; k < 6; k++) {
            twist[k] = AT2(a[TW], i, k);
            AT2(a[HTW], i, k) = twist[k];
            AT2(a[DTW], i, k) = AT3(a[STACK], i, 1, k);
            AT2(a[FROZEN], i, k) = AT3(a[STACK], i, 1, k);
        }
        report(&a[REP], &a[DREP], i, twist);
    }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    return result;
}

static PyMethodDef METHODS[] = {
    {"ik_begin", (PyCFunction)(void (*)(void))ik_begin, METH_FASTCALL,
     "ik_begin(q_init, q, cached_q, qpos, elbow, active) -> bool: ArmKinematics.solve's "
     "start; True when MjData's rows are not at q."},
    {"ik_step", (PyCFunction)(void (*)(void))ik_step, METH_FASTCALL,
     "ik_step(q, qpos, cached_q, site_pos, site_mat, axes, anchors, base, target, F_T_EE, "
     "elbow, active, errors, converged, damping2, tol2, max_step, last) -> int: one pass "
     "of ArmKinematics.solve's loop; the number of arms stepped."},
    {"pose_step", (PyCFunction)(void (*)(void))pose_step, METH_FASTCALL,
     "pose_step(T_c, T_prev, history, stack, q, joint, differences, h, limits) -> int: "
     "pose_derivatives, joint_side and _quiet (1 quiet, 0 not, -1 left to the reference)."},
    {"twist_step", (PyCFunction)(void (*)(void))twist_step, METH_FASTCALL,
     "twist_step(twist, twist_prev, dtwist_prev, stack, q, joint, differences, h, limits) "
     "-> bool: _twist_derivatives, joint_side and _quiet."},
    {"homogeneous_quick", (PyCFunction)(void (*)(void))homogeneous_quick, METH_FASTCALL,
     "homogeneous_quick(values, lo, hi) -> bool: is_homogeneous_wire's quick test."},
    {"twist_target", (PyCFunction)(void (*)(void))twist_target, METH_FASTCALL,
     "twist_target(T, twist, T_tw) -> bool: _twist_target's translation; True when some "
     "twist turns."},
    {"record_pose", (PyCFunction)(void (*)(void))record_pose, METH_FASTCALL,
     "record_pose(T_c, stack, T, history, acceleration_frozen, reported, dreported): "
     "_record of a pose cycle every robot recorded."},
    {"record_twist", (PyCFunction)(void (*)(void))record_twist, METH_FASTCALL,
     "record_twist(T_c, twist, stack, T, h_twist, dtwist, dtwist_frozen, reported, "
     "dreported): _record of a twist cycle every robot recorded."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {
    PyModuleDef_HEAD_INIT, "_cartesian",
    "Cartesian kernels of the 1 kHz cycle (fused copies of numpy reference code).", -1,
    METHODS, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__cartesian(void) { return kernel_module(&MODULE); }
