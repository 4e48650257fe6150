/* C replacements of the contact estimate's rules (fci/contact.py), each with the numpy
 * rule's arguments and ``out`` given, chosen by the backend switch (native.load,
 * contact.py RULES); every constant (the filter's gain, the damping, the published
 * decimals) is an argument from contact.py:
 *
 *   filter_residual(tau_ext, tau_J, m_ddq, bias, alpha, decimals, out)
 *       tau_ext += alpha (tau_J - (m_ddq + bias) - tau_ext), in place; out its rounding
 *   wrench_from_torque(jacobian, tau, damping, decimals, out)
 *       the least-squares wrench (J J^T + damping I) F = J tau, rounded
 *   in_frame(wrench, rotation, decimals, out)
 *       [f R, m R] (R^T f, R^T m), rounded
 *
 * Rounding is numpy's np.round: rint(x 10^d) / 10^d; the wrenches publish a negative
 * zero as zero. filter_residual is elementwise in the numpy rule's order, built without fused
 * multiply-adds (setup.py): the same bits as numpy. The products and the 6 x 6 solve
 * (an elimination with partial pivoting, where numpy calls BLAS and LAPACK) agree with
 * numpy to rounding (~1e-15 relative), so the published, rounded wrench is the same
 * except for a value within ~1e-15 of a rounding boundary
 * (tests/fci/test_contact_parity.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_solve6.h"

/* An int argument >= 0 (the decimals), as the power of ten numpy's round scales by. */
static int scale_get(PyObject *obj, double *scale)
{
    long d = PyLong_AsLong(obj);
    if (d == -1 && PyErr_Occurred()) return -1;
    if (d < 0 || d > 22) {
        PyErr_SetString(PyExc_ValueError, "decimals: expected 0 to 22");
        return -1;
    }
    double s = 1.0;
    for (long k = 0; k < d; k++) s *= 10.0; /* exact up to 10^22 */
    *scale = s;
    return 0;
}

static int double_get(PyObject *obj, double *out, const char *name)
{
    *out = PyFloat_AsDouble(obj);
    if (*out == -1.0 && PyErr_Occurred()) {
        PyErr_Format(PyExc_TypeError, "%s: expected a number", name);
        return -1;
    }
    return 0;
}

/* np.round(x, d): multiply, rint, divide. */
static inline double rounded(double x, double scale)
{
    return rint(x * scale) / scale;
}

/* rounded, then + 0.0: no negative zero (the wrench's). */
static inline double published(double x, double scale)
{
    return rounded(x, scale) + 0.0;
}

/* filter_residual(tau_ext, tau_J, m_ddq, bias, alpha, decimals, out): (n, 7) each. */
static PyObject *filter_residual(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { TAU_EXT, TAU_J, M_DDQ, BIAS, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double alpha, scale;
    if (check_nargs(nargs, 7, "filter_residual") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "tau_ext");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7};
    if (f64_get(args[0], &a[TAU_EXT], 2, s7, 1, "tau_ext") < 0 ||
        num_get(args[1], &a[TAU_J], 2, s7, 0, "tau_J") < 0 ||
        num_get(args[2], &a[M_DDQ], 2, s7, 0, "m_ddq") < 0 ||
        num_get(args[3], &a[BIAS], 2, s7, 0, "bias") < 0 ||
        double_get(args[4], &alpha, "alpha") < 0 || scale_get(args[5], &scale) < 0 ||
        f64_get(args[6], &a[OUT], 2, s7, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++)
        for (int j = 0; j < 7; j++) {
            double residual = num2(&a[TAU_J], i, j) - (num2(&a[M_DDQ], i, j) + num2(&a[BIAS], i, j));
            double tau = AT2(a[TAU_EXT], i, j);
            tau += alpha * (residual - tau);
            AT2(a[TAU_EXT], i, j) = tau;
            AT2(a[OUT], i, j) = rounded(tau, scale);
        }
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* wrench_from_torque(jacobian, tau, damping, decimals, out): (n, 6, 7), (n, 7), float,
 * int, (n, 6). */
static PyObject *wrench_from_torque(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { JAC, TAU, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double damping, scale;
    if (check_nargs(nargs, 5, "wrench_from_torque") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "jacobian");
    if (n < 0) return NULL;
    Py_ssize_t s67[3] = {n, 6, 7}, s7[2] = {n, 7}, s6[2] = {n, 6};
    if (f64_get(args[0], &a[JAC], 3, s67, 0, "jacobian") < 0 ||
        num_get(args[1], &a[TAU], 2, s7, 0, "tau") < 0 ||
        double_get(args[2], &damping, "damping") < 0 || scale_get(args[3], &scale) < 0 ||
        f64_get(args[4], &a[OUT], 2, s6, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double J[6][7], A[6][6], b[6];
        for (int r = 0; r < 6; r++)
            for (int k = 0; k < 7; k++) J[r][k] = AT3(a[JAC], i, r, k);
        for (int r = 0; r < 6; r++) {
            for (int c = r; c < 6; c++) { /* J J^T is symmetric: one triangle */
                double s = 0.0;
                for (int k = 0; k < 7; k++) s += J[r][k] * J[c][k];
                A[r][c] = A[c][r] = s;
            }
            A[r][r] += damping;
            double s = 0.0;
            for (int k = 0; k < 7; k++) s += J[r][k] * num2(&a[TAU], i, k);
            b[r] = s;
        }
        solve6(A, b);
        for (int r = 0; r < 6; r++) AT2(a[OUT], i, r) = published(b[r], scale);
    }
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

/* in_frame(wrench, rotation, decimals, out): (n, 6), (n, 3, 3), int, (n, 6). */
static PyObject *in_frame(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { WRENCH, ROT, OUT, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    double scale;
    if (check_nargs(nargs, 4, "in_frame") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "wrench");
    if (n < 0) return NULL;
    Py_ssize_t s6[2] = {n, 6}, s33[3] = {n, 3, 3};
    if (num_get(args[0], &a[WRENCH], 2, s6, 0, "wrench") < 0 ||
        f64_get(args[1], &a[ROT], 3, s33, 0, "rotation") < 0 || scale_get(args[2], &scale) < 0 ||
        f64_get(args[3], &a[OUT], 2, s6, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double w[6];
        for (int k = 0; k < 6; k++) w[k] = num2(&a[WRENCH], i, k);
        for (int half = 0; half < 2; half++)
            for (int c = 0; c < 3; c++) {
                const double *v = w + 3 * half;
                double s = v[0] * AT3(a[ROT], i, 0, c) + v[1] * AT3(a[ROT], i, 1, c) +
                           v[2] * AT3(a[ROT], i, 2, c);
                AT2(a[OUT], i, 3 * half + c) = published(s, scale);
            }
    }
    result = Py_NewRef(a[OUT].view.obj);
done:
    f64_release_all(a, COUNT);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(filter_residual, "contact.filter_residual, out given."),
    METHOD(wrench_from_torque, "contact.wrench_from_torque, out given."),
    METHOD(in_frame, "contact.in_frame, out given."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_contact, "C replacements of the contact estimate's rules (fci/contact.py).")
