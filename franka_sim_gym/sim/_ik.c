/* The IK of the Cartesian generators, a fused copy of its numpy reference
 * (sim/kinematics.py ArmKinematics.solve):
 *
 *   ik_begin(q_init, q, cached_q, qpos, elbow, active) -> bool
 *       the start of solve: q = q_init, the held elbows set, q written to the private
 *       MjData's qpos; whether q moved off cached_q.
 *   ik_step(q, qpos, cached_q, site_pos, site_mat, axes, anchors, base, target, F_T_EE,
 *           elbow, active, errors, converged, damping2, tol2, max_step, last) -> int
 *       one pass of solve's loop on MjData's rows as mj_kinematics left them
 *       (_evaluate, the error, the convergence test and _update's damped step);
 *       returns how many arms stepped (then qpos holds the new q: run mj_kinematics).
 *
 * The IK's products and its 6x6 solve (an elimination with pivoting in place of
 * LAPACK's) may differ from numpy's in the last bits: the same passes and verdicts, the
 * solution to ~1e-14 (tests/test_native_cartesian.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"

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

static PyMethodDef METHODS[] = {
    {"ik_begin", (PyCFunction)(void (*)(void))ik_begin, METH_FASTCALL,
     "ik_begin(q_init, q, cached_q, qpos, elbow, active) -> bool: ArmKinematics.solve's "
     "start; True when MjData's rows are not at q."},
    {"ik_step", (PyCFunction)(void (*)(void))ik_step, METH_FASTCALL,
     "ik_step(q, qpos, cached_q, site_pos, site_mat, axes, anchors, base, target, F_T_EE, "
     "elbow, active, errors, converged, damping2, tol2, max_step, last) -> int: one pass "
     "of ArmKinematics.solve's loop; the number of arms stepped."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_ik,
              "The Cartesian generators' damped differential IK (a fused copy of numpy code).")
