/* libfranka's isHomogeneousTransformation (native/_homogeneous.h, its only text) on a
 * batch of poses; fci/frames.py loads it (native.require) and puts the wire layout in
 * front:
 *
 *   homogeneous(T (n, 4, 4) row-major, any strides, tol, out (n,) uint8) -> passed
 *
 * ``out[i]`` is 1 where pose i passes; the return value
 * counts them (the caller's "every pose passed" without a reduce). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_homogeneous.h"

static int pose_passes(const F64 *T, Py_ssize_t i, double tol)
{
    /* The wire's records are packed: its doubles may be unaligned, so read them by copy. */
    double m[16];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++)
            memcpy(&m[4 * r + c], T->data + i * T->strides[0] + r * T->strides[1] + c * T->strides[2],
                   sizeof(double));
    return homogeneous_passes(m, tol);
}

static PyObject *homogeneous(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 3, "homogeneous") < 0) return NULL;
    static const Py_ssize_t shape[3] = {-1, 4, 4};
    F64 T;
    if (f64_get(args[0], &T, 3, shape, 0, "T") < 0) return NULL;
    double tol = PyFloat_AsDouble(args[1]);
    if (tol == -1.0 && PyErr_Occurred()) {
        f64_release(&T);
        return NULL;
    }
    Py_ssize_t n = T.shape[0], passed = 0;
    Bytes out;
    if (bytes_get(args[2], &out, n, 1, "out") < 0) {
        f64_release(&T);
        return NULL;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        int ok = pose_passes(&T, i, tol);
        BYTE1(out, i) = (unsigned char)ok;
        passed += ok;
    }
    bytes_release(&out);
    f64_release(&T);
    return PyLong_FromSsize_t(passed);
}

static PyMethodDef METHODS[] = {
    METHOD(homogeneous, "homogeneous(T, tol, out) -> passed: libfranka's "
                        "isHomogeneousTransformation on (n, 4, 4) row-major poses."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_frames, "libfranka's isHomogeneousTransformation (fci/frames.py).")
