/* The Jacobian at a point of the arm's last link, the one text of sim/dynamics.py
 * jacobian_at (issue 38: no numpy twin), which the contact estimate (at K), the load's
 * weight, the Cartesian servo and the IK read:
 *
 *   jacobian_at(axes, anchors, point, out)
 *       (n, 6, 7): column j is [z_j x (p - o_j); z_j], axes / anchors (n, 7, 3), point
 *       (n, 3)
 *
 * The rows are native/_jacobian.h's (the contact sensing's plan runs them too);
 * tests/sim/test_dynamics.py holds them to MuJoCo's own mj_jac. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "_arrays.h"
#include "_jacobian.h"

static PyObject *jacobian_at(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { AXES, ANCHORS, POINT, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    if (check_nargs(nargs, 4, "jacobian_at") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "axes");
    if (n < 0) return NULL;
    Py_ssize_t s73[3] = {n, 7, 3}, s3[2] = {n, 3}, s67[3] = {n, 6, 7};
    if (f64_get(args[0], &a[AXES], 3, s73, 0, "axes") < 0 ||
        f64_get(args[1], &a[ANCHORS], 3, s73, 0, "anchors") < 0 ||
        f64_get(args[2], &a[POINT], 2, s3, 0, "point") < 0 ||
        f64_get(args[3], &a[OUT], 3, s67, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) jacobian_row(&a[AXES], &a[ANCHORS], &a[POINT], i, &a[OUT]);
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(jacobian_at, "dynamics.jacobian_at, out given."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_dynamics, "The arms' Jacobian at a point (sim/dynamics.py jacobian_at).")
