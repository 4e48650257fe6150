/* The IK of the Cartesian generators, a fused copy of its numpy reference
 * (sim/kinematics.py ArmKinematics.solve):
 *
 *   ik_solve(q_init, q, cached_q, qpos, site_pos, site_mat, axes, anchors, base, target,
 *            F_T_EE, elbow, active, errors, converged, damping2, tol2, max_step,
 *            max_iterations, rows_valid, kinematics)
 *       the whole solve in one call: q = q_init (the held elbows set), then damped
 *       Gauss-Newton passes on the private MjData's rows, with MuJoCo's mj_kinematics
 *       (``kinematics``: its address and the model's and data's) after every pass that
 *       stepped; errors (2, n) and converged (n,) as the last pass found them.
 *
 * The solve itself is native/_ik_core.h, which the Cartesian generators' plain cycle
 * (fci/_cartesian_rules.c) shares. The IK's products and its 6x6 solve (an elimination
 * with pivoting in place of LAPACK's) may differ from numpy's in the last bits: the same
 * passes and verdicts, the solution to ~1e-14 (tests/test_native_cartesian.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_ik_core.h"

/* ik_solve(q_init, q, cached_q, qpos, site_pos, site_mat, axes, anchors, base, target,
 *          F_T_EE, elbow, active, errors, converged, damping2, tol2, max_step,
 *          max_iterations, rows_valid, kinematics)
 *
 * F_T_EE (n, 4, 4) or None (the flange); elbow (n,) (joint 3 held where finite) or
 * None; active (n,) bool or None (every arm); rows_valid: MjData's rows are at cached_q
 * (False: mj_kinematics runs first whatever q is). */
static PyObject *ik_solve(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { Q_INIT, Q, CACHED, QPOS, SITE_POS, SITE_MAT, AXES, ANCHORS, BASE, TARGET, ERRORS,
           COUNT };
    F64 a[COUNT], F, elbow;
    Mask active, converged;
    Kinematics kin;
    memset(a, 0, sizeof(a));
    memset(&F, 0, sizeof(F));
    memset(&elbow, 0, sizeof(elbow));
    memset(&active, 0, sizeof(active));
    memset(&converged, 0, sizeof(converged));
    PyObject *result = NULL;
    if (check_nargs(nargs, 21, "ik_solve") < 0) return NULL;
    double damping2 = PyFloat_AsDouble(args[15]), tol2 = PyFloat_AsDouble(args[16]);
    double max_step = PyFloat_AsDouble(args[17]);
    long max_iterations = PyLong_AsLong(args[18]);
    int rows_valid = PyObject_IsTrue(args[19]);
    if (PyErr_Occurred() || rows_valid < 0) return NULL;
    if (max_iterations < 0 || max_iterations > 1000) {
        PyErr_SetString(PyExc_ValueError, "max_iterations: expected 0 to 1000");
        return NULL;
    }
    if (kinematics_get(args[20], &kin) < 0) return NULL;
    Py_ssize_t n = leading(args[0], "q_init");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, s3[2] = {n, 3}, s33[3] = {n, 3, 3}, s73[3] = {n, 7, 3};
    Py_ssize_t s44[3] = {n, 4, 4}, s1[1] = {n}, s2n[2] = {2, n};
    if (f64_get(args[0], &a[Q_INIT], 2, s7, 0, "q_init") < 0 ||
        f64_get(args[1], &a[Q], 2, s7, 1, "q") < 0 ||
        f64_get(args[2], &a[CACHED], 2, s7, 1, "cached_q") < 0 ||
        f64_get(args[3], &a[QPOS], 2, s7, 1, "qpos") < 0 ||
        f64_get(args[4], &a[SITE_POS], 2, s3, 0, "site_pos") < 0 ||
        f64_get(args[5], &a[SITE_MAT], 3, s33, 0, "site_mat") < 0 ||
        f64_get(args[6], &a[AXES], 3, s73, 0, "axes") < 0 ||
        f64_get(args[7], &a[ANCHORS], 3, s73, 0, "anchors") < 0 ||
        f64_get(args[8], &a[BASE], 2, s3, 0, "base") < 0 ||
        f64_get(args[9], &a[TARGET], 3, s44, 0, "target") < 0 ||
        (args[10] != Py_None && f64_get(args[10], &F, 3, s44, 0, "F_T_EE") < 0) ||
        (args[11] != Py_None && f64_get(args[11], &elbow, 1, s1, 0, "elbow") < 0) ||
        mask_get(args[12], &active, n, 0, "active") < 0 ||
        f64_get(args[13], &a[ERRORS], 2, s2n, 1, "errors") < 0 ||
        mask_get(args[14], &converged, n, 1, "converged") < 0)
        goto done;
    if (!converged.data) {
        PyErr_SetString(PyExc_ValueError, "converged: expected a bool array, not None");
        goto done;
    }
    IkProblem p = {
        &a[Q_INIT], &a[Q], &a[CACHED], &a[QPOS], &a[SITE_POS], &a[SITE_MAT], &a[AXES],
        &a[ANCHORS], &a[BASE], &a[TARGET], &F, &elbow, &active, &a[ERRORS],
        (char *)converged.data, converged.stride, damping2, tol2, max_step, (int)max_iterations,
    };
    if (ik_solve_core(&p, &kin, n, rows_valid) == 0) result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    f64_release(&F);
    f64_release(&elbow);
    mask_release(&active);
    mask_release(&converged);
    return result;
}

static PyMethodDef METHODS[] = {
    {"ik_solve", (PyCFunction)(void (*)(void))ik_solve, METH_FASTCALL,
     "ik_solve(q_init, q, cached_q, qpos, site_pos, site_mat, axes, anchors, base, target, "
     "F_T_EE, elbow, active, errors, converged, damping2, tol2, max_step, max_iterations, "
     "rows_valid, kinematics): ArmKinematics.solve in one call."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_ik,
              "The Cartesian generators' damped differential IK (a fused copy of numpy code).")
