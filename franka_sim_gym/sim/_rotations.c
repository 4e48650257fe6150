/* The rotation library (sim/rotations.py) over (n, ...) arrays: its only text, one
 * rotation at a time in native/_rotation.h (shared with envs/_client_filters.c's pose
 * rules). sim/rotations.py loads the module (native.require), hands over its thresholds
 * (configure) and puts numpy's leading axes in front:
 *
 *   exponential(rotvec (n, 3), out (n, 3, 3))            rotation_exp (Rodrigues)
 *   logarithm(R (n, 3, 3), out (n, 3))                   rotation_log
 *   relative_logarithm(R_a, R_b (n, 3, 3), out (n, 3))   rotation_log(R_a^T R_b)
 *   to_quaternion(R (n, 3, 3), out (n, 4))               rotation_to_quaternion (Shepperd)
 *   to_rotation(q (n, 4), out (n, 3, 3))                 quaternion_to_rotation
 *   slerp(q0 (n, 4), q1 (n, 4), t (n,), out (n, 4))      quaternion_slerp (Eigen's)
 *   nearest(R (n, 3, 3), out (n, 3, 3))                  nearest_rotation
 *
 * Built without fused multiply-adds (setup.py). Inputs are assumed finite. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"
#include "_kernel.h"
#include "_rotation.h"

static int CONFIGURED = 0;

/* configure(near_pi, turning_above, series_below, slerp_linear): sim/rotations.py's. */
static PyObject *configure(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    double v[4];
    if (positive_constants(args, nargs, 4, v) < 0) return NULL;
    rotation_configure(v);
    CONFIGURED = 1;
    Py_RETURN_NONE;
}

/* The address of value j of row i of an (n, k) argument, or of an (n, 3, 3) one taken
 * row-major. Read and written by copy: views of the wire's packed records (a pose
 * command's rotation) may be unaligned. */
static char *row_value(const F64 *a, Py_ssize_t i, int j)
{
    char *row = a->data + i * a->strides[0];
    if (a->ndim == 2) return row + j * a->strides[1];
    return row + (j / 3) * a->strides[1] + (j % 3) * a->strides[2];
}

static void row_at(const F64 *a, Py_ssize_t i, int k, double *out)
{
    for (int j = 0; j < k; j++) memcpy(&out[j], row_value(a, i, j), sizeof(double));
}

static void row_put(const F64 *a, Py_ssize_t i, int k, const double *v)
{
    for (int j = 0; j < k; j++) memcpy(row_value(a, i, j), &v[j], sizeof(double));
}

static void exponential_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double rv[3], R[9];
        row_at(&a[0], i, 3, rv);
        rotation_exp(rv, R);
        row_put(&a[1], i, 9, R);
    }
}
KERNEL(exponential, 1, ARRAY(F64_IN, "rotvec", 2, ROWS, 3), ARRAY(OUT, "out", 3, ROWS, 3, 3))

static void logarithm_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double R[9], rv[3];
        row_at(&a[0], i, 9, R);
        rotation_log(R, rv);
        row_put(&a[1], i, 3, rv);
    }
}
KERNEL(logarithm, 1, ARRAY(F64_IN, "R", 3, ROWS, 3, 3), ARRAY(OUT, "out", 2, ROWS, 3))

static void relative_logarithm_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double A[9], B[9], rv[3];
        row_at(&a[0], i, 9, A);
        row_at(&a[1], i, 9, B);
        relative_rotation_log(A, B, rv);
        row_put(&a[2], i, 3, rv);
    }
}
KERNEL(relative_logarithm, 1, ARRAY(F64_IN, "R_a", 3, ROWS, 3, 3),
       ARRAY(F64_IN, "R_b", 3, ROWS, 3, 3), ARRAY(OUT, "out", 2, ROWS, 3))

static void to_quaternion_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double R[9], q[4];
        row_at(&a[0], i, 9, R);
        rotation_to_quaternion(R, q);
        row_put(&a[1], i, 4, q);
    }
}
KERNEL(to_quaternion, 0, ARRAY(F64_IN, "R", 3, ROWS, 3, 3), ARRAY(OUT, "out", 2, ROWS, 4))

static void to_rotation_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double q[4], R[9];
        row_at(&a[0], i, 4, q);
        quaternion_to_rotation(q, R);
        row_put(&a[1], i, 9, R);
    }
}
KERNEL(to_rotation, 0, ARRAY(F64_IN, "q", 2, ROWS, 4), ARRAY(OUT, "out", 3, ROWS, 3, 3))

static void slerp_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double q0[4], q1[4], q[4];
        row_at(&a[0], i, 4, q0);
        row_at(&a[1], i, 4, q1);
        double t;
        memcpy(&t, a[2].data + i * a[2].strides[0], sizeof(double));
        quaternion_slerp(q0, q1, t, q);
        row_put(&a[3], i, 4, q);
    }
}
KERNEL(slerp, 1, ARRAY(F64_IN, "q0", 2, ROWS, 4), ARRAY(F64_IN, "q1", 2, ROWS, 4),
       ARRAY(F64_IN, "t", 1, ROWS), ARRAY(OUT, "out", 2, ROWS, 4))

static void nearest_rows(const F64 *a, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double R[9];
        row_at(&a[0], i, 9, R);
        nearest_rotation(R);
        row_put(&a[1], i, 9, R);
    }
}
KERNEL(nearest, 0, ARRAY(F64_IN, "R", 3, ROWS, 3, 3), ARRAY(OUT, "out", 3, ROWS, 3, 3))

static PyMethodDef METHODS[] = {
    METHOD(configure, "configure(near_pi, turning_above, series_below, slerp_linear): "
                      "sim/rotations.py's thresholds."),
    METHOD(exponential, "exponential(rotvec, out): rotation vectors to rotations (Rodrigues)."),
    METHOD(logarithm, "logarithm(R, out): rotations to rotation vectors."),
    METHOD(relative_logarithm, "relative_logarithm(R_a, R_b, out): rotation_log(R_a^T R_b)."),
    METHOD(to_quaternion, "to_quaternion(R, out): rotations to quaternions (Shepperd)."),
    METHOD(to_rotation, "to_rotation(q, out): unit quaternions to rotations."),
    METHOD(slerp, "slerp(q0, q1, t, out): Eigen's q0.slerp(t, q1)."),
    METHOD(nearest, "nearest(R, out): the rotation nearest each nearly orthonormal matrix."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_rotations, "The rotation library's one text (sim/rotations.py).")
