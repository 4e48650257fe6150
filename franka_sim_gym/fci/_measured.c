/* The measured joint fields of the RobotState (docs/robot-state.md; docs/reality.md,
 * "Sensors"), their only text; fci/state.py StateWriter.write_measured (the ideal robot)
 * and fci/reality RobotReality.write_measured (the robot's sensors) call it:
 *
 *   measured(q, dq, tau, noise, q_out, theta_out, dq_out, dtheta_out, tau_out, dtau_out, rate)
 *
 * From the physics' q, dq, tau_J (n, 7) and the sensors' noise of the cycle (n, 21: q | dq
 * | tau_J, or None for the ideal robot): q and dq as the sensors read them (physics plus
 * noise), theta and dtheta the same (no joint elasticity is modelled: the motor side reads
 * the link side), tau_J likewise, and dtau_J its backward difference against the tau_J
 * published before ((tau_J - tau_J_prev) * rate, rate = 1 / dt: fci/tables.py DELTA_T),
 * read from tau_out before it is overwritten. Each sum rounds as written (one addition;
 * no noise, no addition: a copy keeps a -0.0). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "_arrays.h"

static PyObject *measured(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { Q, DQ, TAU, NOISE, Q_OUT, THETA, DQ_OUT, DTHETA, TAU_OUT, DTAU, COUNT };
    static const char *names[COUNT] = {"q", "dq", "tau", "noise", "q_out", "theta_out",
                                       "dq_out", "dtheta_out", "tau_out", "dtau_out"};
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double rate;
    if (check_nargs(nargs, 11, "measured") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "q");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7}, s21[2] = {n, 21};
    const int noisy = args[NOISE] != Py_None;
    for (int k = 0; k < COUNT; k++) {
        if (k == NOISE && !noisy) continue;
        if (f64_get(args[k], &a[k], 2, k == NOISE ? s21 : s7, k >= Q_OUT, names[k]) < 0)
            goto done;
    }
    {
        PyObject *r = args[10];
        rate = PyFloat_AsDouble(r);
        if (rate == -1.0 && PyErr_Occurred()) goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++)
        for (int j = 0; j < 7; j++) {
            double q = AT2(a[Q], i, j), dq = AT2(a[DQ], i, j), tau = AT2(a[TAU], i, j);
            if (noisy) {
                q = q + AT2(a[NOISE], i, j);
                dq = dq + AT2(a[NOISE], i, 7 + j);
                tau = tau + AT2(a[NOISE], i, 14 + j);
            }
            AT2(a[Q_OUT], i, j) = q;
            AT2(a[THETA], i, j) = q;
            AT2(a[DQ_OUT], i, j) = dq;
            AT2(a[DTHETA], i, j) = dq;
            AT2(a[DTAU], i, j) = (tau - AT2(a[TAU_OUT], i, j)) * rate;
            AT2(a[TAU_OUT], i, j) = tau;
        }
    result = Py_NewRef(Py_None);
done:
    f64_release_all(a, COUNT);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(measured, "The measured joint fields (q, theta, dq, dtheta, tau_J, dtau_J) of a cycle."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_measured, "The RobotState's measured joint fields: their only text (fci/state.py, fci/reality).")
