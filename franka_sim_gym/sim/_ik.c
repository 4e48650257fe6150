/* The IK solve, sim/kinematics.py ArmKinematics.solve: its one text (issue 38: no numpy
 * twin; its settings and result are sim/ik.py's), required (native.require):
 *
 *   ik_solve(q_init, q, target, F_T_EE, elbow, active, rows_valid, ik)
 *       the whole solve in one call: q = q_init (the held elbows set), then damped
 *       Gauss-Newton passes on the private MjData's rows, with MuJoCo's mj_kinematics
 *       after every pass that stepped; the solver's errors (2, n) and converged (n,) as
 *       the last pass found them (ik: ArmKinematics.native_solve, the solver's arrays,
 *       settings and the mj_kinematics addresses).
 *
 * The solve itself is native/_ik_core.h; tests/sim/test_ik.py holds it to the poses it
 * solves for (MuJoCo's forward kinematics), the held elbow, the capped step and the
 * verdicts. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_ik_core.h"

/* ik_solve(q_init, q, target, F_T_EE, elbow, active, rows_valid, ik)
 *
 * q_init (n, 7) the start; q (n, 7) receives the solution; target (n, 4, 4); F_T_EE
 * (n, 4, 4) or None (the flange); elbow (n,) (joint 3 held where finite) or None; active
 * (n,) bool or None (every arm); rows_valid: MjData's rows are at the solver's cached_q
 * (False: mj_kinematics runs first whatever q is); ik: ArmKinematics.native_solve. */
static PyObject *ik_solve(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { Q_INIT, Q, TARGET, F_EE, ELBOW, COUNT };
    F64 a[COUNT];
    Mask active;
    IkSolver solver;
    memset(a, 0, sizeof(a));
    memset(&active, 0, sizeof(active));
    memset(&solver, 0, sizeof(solver));
    PyObject *result = NULL;
    if (check_nargs(nargs, 8, "ik_solve") < 0) return NULL;
    int rows_valid = PyObject_IsTrue(args[6]);
    if (rows_valid < 0) return NULL;
    Py_ssize_t n = leading(args[0], "q_init");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, s44[3] = {n, 4, 4}, s1[1] = {n};
    if (f64_get(args[0], &a[Q_INIT], 2, s7, 0, "q_init") < 0 ||
        f64_get(args[1], &a[Q], 2, s7, 1, "q") < 0 ||
        f64_get(args[2], &a[TARGET], 3, s44, 0, "target") < 0 ||
        (args[3] != Py_None && f64_get(args[3], &a[F_EE], 3, s44, 0, "F_T_EE") < 0) ||
        (args[4] != Py_None && f64_get(args[4], &a[ELBOW], 1, s1, 0, "elbow") < 0) ||
        bytes_or_none_get(args[5], &active, n, 0, "active") < 0 || ik_solver_get(args[7], n, &solver) < 0)
        goto done;
    IkProblem p =
        ik_problem(&solver, &a[Q_INIT], &a[Q], &a[TARGET], &a[F_EE], &a[ELBOW], &active);
    if (ik_solve_core(&p, &solver.kin, n, rows_valid) == 0) result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    bytes_release(&active);
    ik_solver_release(&solver);
    return result;
}

static PyMethodDef METHODS[] = {
    {"ik_solve", (PyCFunction)(void (*)(void))ik_solve, METH_FASTCALL,
     "ik_solve(q_init, q, target, F_T_EE, elbow, active, rows_valid, ik): "
     "ArmKinematics.solve in one call (ik: ArmKinematics.native_solve)."},
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_ik,
              "The damped differential IK solve (sim/kinematics.py ArmKinematics.solve).")
