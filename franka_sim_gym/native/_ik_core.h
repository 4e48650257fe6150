/* The IK's damped Gauss-Newton solve, the one text of sim/kinematics.py
 * ArmKinematics.solve (sim/_ik.c calls it; its settings and result are sim/ik.py's).
 *
 * The evaluation reads the arms' rows of a private MjData (the flange site's position
 * and rotation, the joints' axes and anchors) as MuJoCo's mj_kinematics leaves them; the
 * solve calls mj_kinematics itself, through the pointer the Python bindings' own
 * libmujoco exports (sim/ik.py mj_kinematics_addresses), so the kinematics stay
 * MuJoCo's and the whole solve is one C call. Its 6x6 solve is an elimination with
 * partial pivoting (native/_solve6.h). No rule of the robot lives here. */
#ifndef FRANKA_SIM_GYM_NATIVE_IK_CORE_H
#define FRANKA_SIM_GYM_NATIVE_IK_CORE_H

#include <Python.h>
#include <math.h>
#include <string.h>

#include "_arrays.h"
#include "_solve6.h"

/* An (n,) one-byte flag argument (bool or uint8), or None (data NULL: mask_at's
 * ``otherwise``). */
typedef Bytes Mask;

static inline int mask_at(const Mask *m, Py_ssize_t i, int otherwise)
{
    return m->data ? m->data[i * m->stride] != 0 : otherwise;
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

/* One arm's damped Gauss-Newton step J^T (J J^T + lambda^2 I)^-1 e (sim/ik.py
 * damped_step), the elbow joint's column zeroed where the elbow is held (elbow_joint:
 * sim/ik.py ELBOW_JOINT, or -1). */
static void damped_step(const F64 *axes, const F64 *anchors, Py_ssize_t i, const Pose *pose,
                        int elbow_joint, const double e[6], double damping2, double step[7])
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
    if (elbow_joint >= 0)
        for (int r = 0; r < 6; r++) J[r][elbow_joint] = 0.0;
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

/* MuJoCo's mj_kinematics(m, d) on the IK's private MjData. */
typedef void (*KinematicsFn)(const void *model, void *data);
typedef struct {
    KinematicsFn run;
    const void *model;
    void *data;
} Kinematics;

/* The (function, model, data) addresses sim/kinematics.py hands over as a tuple of three
 * ints (none zero). Returns 0, or -1 with a ValueError. */
static int kinematics_get(PyObject *obj, Kinematics *k)
{
    if (!PyTuple_Check(obj) || PyTuple_GET_SIZE(obj) != 3) {
        PyErr_SetString(PyExc_ValueError,
                        "kinematics: expected a tuple (mj_kinematics, model, data) of addresses");
        return -1;
    }
    void *p[3];
    for (int i = 0; i < 3; i++) {
        p[i] = PyLong_AsVoidPtr(PyTuple_GET_ITEM(obj, i));
        if (!p[i]) {
            if (!PyErr_Occurred())
                PyErr_SetString(PyExc_ValueError, "kinematics: a null address");
            return -1;
        }
    }
    k->run = (KinematicsFn)p[0];
    k->model = p[1];
    k->data = p[2];
    return 0;
}

/* What one solve reads and writes: the start, the solution, MjData's rows and the
 * verdicts (all (n, ...) as sim/kinematics.py names them; F, elbow and active may be
 * absent: data NULL). */
typedef struct {
    const F64 *q_init, *q, *cached_q, *qpos;
    const F64 *site_pos, *site_mat, *axes, *anchors, *base;
    const F64 *target, *F, *elbow;
    const Mask *active;
    const F64 *errors;
    char *converged;
    Py_ssize_t converged_stride;
    double damping2, tol2, max_step;
    int max_iterations, elbow_joint;
} IkProblem;

/* sim/kinematics.py ArmKinematics.native_solve, borrowed: the solver's own arrays (its
 * cache, MjData's rows, the verdicts), its settings and the mj_kinematics addresses. */
typedef struct {
    F64 cached_q, qpos, site_pos, site_mat, axes, anchors, base, errors;
    Mask converged;
    double damping2, tol2, max_step;
    int max_iterations, elbow_joint;
    Kinematics kin;
} IkSolver;

static void ik_solver_release(IkSolver *s)
{
    f64_release(&s->cached_q);
    f64_release(&s->qpos);
    f64_release(&s->site_pos);
    f64_release(&s->site_mat);
    f64_release(&s->axes);
    f64_release(&s->anchors);
    f64_release(&s->base);
    f64_release(&s->errors);
    bytes_release(&s->converged);
}

/* Borrow native_solve's tuple (cached_q, qpos, site_pos, site_mat, axes, anchors, base,
 * errors, converged, damping2, tol2, max_step, max_iterations, kinematics, elbow_joint)
 * for n arms (every setting and constant from sim/kinematics.py and sim/ik.py).
 * Returns 0, or -1 with a ValueError (release with ik_solver_release either way). */
static int ik_solver_get(PyObject *obj, Py_ssize_t n, IkSolver *s)
{
    memset(s, 0, sizeof(*s));
    if (!PyTuple_Check(obj) || PyTuple_GET_SIZE(obj) != 15) {
        PyErr_SetString(PyExc_ValueError, "ik: expected ArmKinematics.native_solve's tuple");
        return -1;
    }
    PyObject *const *t = &PyTuple_GET_ITEM(obj, 0);
    Py_ssize_t s7[2] = {n, 7}, s3[2] = {n, 3}, s33[3] = {n, 3, 3}, s73[3] = {n, 7, 3};
    Py_ssize_t s2n[2] = {2, n};
    if (f64_get(t[0], &s->cached_q, 2, s7, 1, "cached_q") < 0 ||
        f64_get(t[1], &s->qpos, 2, s7, 1, "qpos") < 0 ||
        f64_get(t[2], &s->site_pos, 2, s3, 0, "site_pos") < 0 ||
        f64_get(t[3], &s->site_mat, 3, s33, 0, "site_mat") < 0 ||
        f64_get(t[4], &s->axes, 3, s73, 0, "axes") < 0 ||
        f64_get(t[5], &s->anchors, 3, s73, 0, "anchors") < 0 ||
        f64_get(t[6], &s->base, 2, s3, 0, "base") < 0 ||
        f64_get(t[7], &s->errors, 2, s2n, 1, "errors") < 0 ||
        bytes_or_none_get(t[8], &s->converged, n, 1, "converged") < 0)
        return -1;
    if (!s->converged.data) {
        PyErr_SetString(PyExc_ValueError, "converged: expected a bool array, not None");
        return -1;
    }
    s->damping2 = PyFloat_AsDouble(t[9]);
    s->tol2 = PyFloat_AsDouble(t[10]);
    s->max_step = PyFloat_AsDouble(t[11]);
    long iterations = PyLong_AsLong(t[12]);
    if (PyErr_Occurred()) return -1;
    if (iterations < 0 || iterations > 1000) {
        PyErr_SetString(PyExc_ValueError, "max_iterations: expected 0 to 1000");
        return -1;
    }
    s->max_iterations = (int)iterations;
    long elbow_joint = PyLong_AsLong(t[14]);
    if (PyErr_Occurred()) return -1;
    if (elbow_joint < 0 || elbow_joint > 6) {
        PyErr_SetString(PyExc_ValueError, "elbow_joint: expected a joint index 0 to 6");
        return -1;
    }
    s->elbow_joint = (int)elbow_joint;
    return kinematics_get(t[13], &s->kin);
}

/* The problem of solving ``target`` from q_init into q with solver s (F, elbow: data NULL
 * where absent; active: data NULL for every arm). */
static IkProblem ik_problem(const IkSolver *s, const F64 *q_init, const F64 *q,
                            const F64 *target, const F64 *F, const F64 *elbow,
                            const Mask *active)
{
    IkProblem p = {
        q_init, q, &s->cached_q, &s->qpos, &s->site_pos, &s->site_mat, &s->axes,
        &s->anchors, &s->base, target, F, elbow, active, &s->errors,
        (char *)s->converged.data, s->converged.stride, s->damping2, s->tol2, s->max_step,
        s->max_iterations, s->elbow_joint,
    };
    return p;
}

/* One pass of solve's loop, MjData's rows being at q: every arm's error (errors (2, n):
 * position and rotation error, as IkResult reports them) and verdict; then, unless every
 * arm converged, no active arm is left or ``last``, the damped step of the active
 * unconverged arms (each capped at max_step per joint; the others add zero, as the
 * reference's masked step does), q += step, qpos = cached_q = q. Returns the number of
 * arms stepped; ``steps`` is n * 7 scratch. */
static Py_ssize_t ik_pass(const IkProblem *p, Py_ssize_t n, int last, double *steps)
{
    const F64 *F = p->F && p->F->data ? p->F : NULL;
    Py_ssize_t n_ok = 0, n_todo = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        Pose pose;
        double e[6];
        arm_pose(p->site_pos, p->site_mat, p->base, F, i, &pose);
        pose_error(p->target, i, &pose, e);
        double err2_p = 0.0, err2_r = 0.0;
        for (int k = 0; k < 3; k++) {
            err2_p += e[k] * e[k];
            err2_r += e[3 + k] * e[3 + k];
        }
        AT2(*p->errors, 0, i) = sqrt(err2_p);
        AT2(*p->errors, 1, i) = sqrt(err2_r);
        int ok_p = err2_p <= p->tol2, ok_r = err2_r <= p->tol2;
        n_ok += ok_p + ok_r;
        p->converged[i * p->converged_stride] = (char)(ok_p && ok_r);
        n_todo += mask_at(p->active, i, 1) && !(ok_p && ok_r);
    }
    if (n_ok == 2 * n || last || n_todo == 0) return 0;
    memset(steps, 0, (size_t)n * 7 * sizeof(double));
    int any_big = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!mask_at(p->active, i, 1) || p->converged[i * p->converged_stride]) continue;
        Pose pose;
        double e[6];
        arm_pose(p->site_pos, p->site_mat, p->base, F, i, &pose);
        pose_error(p->target, i, &pose, e);
        int held = p->elbow && p->elbow->data && isfinite(AT1(*p->elbow, i));
        damped_step(p->axes, p->anchors, i, &pose, held ? p->elbow_joint : -1, e, p->damping2,
                    &steps[7 * i]);
        for (int j = 0; j < 7; j++) any_big |= fabs(steps[7 * i + j]) > p->max_step;
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
        double m = (isnan(biggest) || biggest >= p->max_step) ? biggest : p->max_step;
        double ratio = p->max_step / m;
        double factor = isnan(ratio) ? ratio : (1.0 <= ratio ? 1.0 : ratio);
        for (int j = 0; j < 7; j++) step[j] *= factor;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) {
            double v = AT2(*p->q, i, j) + steps[7 * i + j];
            AT2(*p->q, i, j) = v;
            AT2(*p->qpos, i, j) = v;
            AT2(*p->cached_q, i, j) = v;
        }
    }
    return n_todo;
}

/* ArmKinematics.solve, whole: q = q_init with the held elbows set (joint 3 = elbow where
 * the arm is active and its elbow finite), qpos = cached_q = q; mj_kinematics where
 * MjData's rows are not at q already (q moved off cached_q, or NaN, or
 * ``rows_valid`` false); then up to max_iterations passes, mj_kinematics after each that
 * stepped. Returns 0, or -1 with MemoryError. */
static int ik_solve_core(const IkProblem *p, const Kinematics *kin, Py_ssize_t n, int rows_valid)
{
    int moved = !rows_valid;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) AT2(*p->q, i, j) = AT2(*p->q_init, i, j);
        if (p->elbow && p->elbow->data && mask_at(p->active, i, 1) &&
            isfinite(AT1(*p->elbow, i)))
            AT2(*p->q, i, p->elbow_joint) = AT1(*p->elbow, i);
        for (int j = 0; j < 7; j++) {
            double v = AT2(*p->q, i, j);
            if (!(v == AT2(*p->cached_q, i, j))) moved = 1;
            AT2(*p->cached_q, i, j) = v;
            AT2(*p->qpos, i, j) = v;
        }
    }
    if (moved) kin->run(kin->model, kin->data);
    double local[7 * 16];
    double *steps = n <= 16 ? local : PyMem_Malloc((size_t)n * 7 * sizeof(double));
    if (!steps) {
        PyErr_NoMemory();
        return -1;
    }
    for (int iteration = 0; iteration <= p->max_iterations; iteration++) {
        if (!ik_pass(p, n, iteration == p->max_iterations, steps)) break;
        kin->run(kin->model, kin->data);
    }
    if (steps != local) PyMem_Free(steps);
    return 0;
}

#endif
