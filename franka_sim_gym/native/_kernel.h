/* The call of a C rule from Python: its array arguments checked against the rule's
 * declared shapes and borrowed, the rule run row by row, the result (the last argument)
 * returned. Shared by the kernel modules whose rules take (n, ...) arrays, ``out`` last
 * (envs/_client_filters.c, sim/_rotations.c). A module using KERNEL declares
 * ``static int CONFIGURED`` first: its configure() sets it, and a rule declared as reading
 * the constants refuses to run before. No rule of the robot lives here. */
#ifndef FRANKA_SIM_GYM_NATIVE_KERNEL_H
#define FRANKA_SIM_GYM_NATIVE_KERNEL_H

#include <math.h>

#include "_arrays.h"

/* How a rule takes argument k: a float64 array (NUM_IN: float32 too, the wire state's
 * fields; OUT: the writable result, always the last argument). A value the same for every
 * robot (a limit, a gain) is a broadcast view: numpy's stride-0 arrays are read as such. */
enum { F64_IN, NUM_IN, OUT };
/* An array axis of length ROWS is the robot axis, COLS the columns: the first argument's
 * first and second axes (any length on the first argument itself). */
#define ROWS (-1)
#define COLS (-2)
#define MAX_ARGS 9 /* the most a rule takes: limit_positions's */

typedef struct {
    int kind, ndim;
    Py_ssize_t shape[3];
    const char *name; /* as errors name it */
} Arg;

typedef struct {
    const char *name;
    const int *configured; /* the module's configure() flag, NULL if the rule reads none */
    void (*rows)(const F64 *a, Py_ssize_t n); /* a[k]: argument k */
    const Arg *args;
    int nargs;
} Kernel;

static PyObject *call_kernel(const Kernel *kernel, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, kernel->nargs, kernel->name) < 0) return NULL;
    if (kernel->configured && !*kernel->configured) {
        PyErr_Format(PyExc_RuntimeError, "%s: the module's configure(...) first", kernel->name);
        return NULL;
    }
    F64 a[MAX_ARGS];
    memset(a, 0, sizeof(a));
    PyObject *result = NULL;
    Py_ssize_t n = -1, cols = -1; /* "any" until the first argument is read */
    for (int k = 0; k < kernel->nargs; k++) {
        const Arg *arg = &kernel->args[k];
        Py_ssize_t shape[3];
        for (int d = 0; d < arg->ndim; d++)
            shape[d] = arg->shape[d] == ROWS ? n : arg->shape[d] == COLS ? cols : arg->shape[d];
        if ((arg->kind == NUM_IN ? num_get(args[k], &a[k], arg->ndim, shape, 0, arg->name)
                                 : f64_get(args[k], &a[k], arg->ndim, shape, arg->kind == OUT,
                                           arg->name)) < 0)
            goto done;
        if (k == 0) {
            n = a[0].shape[0];
            cols = a[0].ndim > 1 ? a[0].shape[1] : -1;
        }
    }
    kernel->rows(a, n);
    result = Py_NewRef(a[kernel->nargs - 1].view.obj);
done:
    f64_release_all(a, kernel->nargs);
    return result;
}

/* The arguments of a rule (ARRAY(kind, name, ndim, axes...), in order)
 * and the module function NAME that calls it: NAME_rows on every robot. */
#define ARRAY(kind, name, ndim, ...) {kind, ndim, {__VA_ARGS__}, name}
#define KERNEL(name, configured, ...)                                                     \
    static const Arg name##_args[] = {__VA_ARGS__};                                        \
    /* (a rule of more than MAX_ARGS arguments does not compile) */                        \
    typedef char name##_fits[sizeof(name##_args) / sizeof(Arg) <= MAX_ARGS ? 1 : -1];      \
    static const Kernel name##_kernel = {#name, (configured) ? &CONFIGURED : NULL,         \
                                         name##_rows, name##_args,                         \
                                         (int)(sizeof(name##_args) / sizeof(Arg))};       \
    static PyObject *name(PyObject *self, PyObject *const *args, Py_ssize_t nargs)         \
    {                                                                                      \
        (void)self;                                                                        \
        return call_kernel(&name##_kernel, args, nargs);                                   \
    }

/* configure()'s arguments: ``count`` positive finite floats into ``out``. Returns 0, or
 * -1 with the error set (and ``out`` unchanged in part or whole: the caller keeps its
 * constants until every value checked). */
static inline int positive_constants(PyObject *const *args, Py_ssize_t nargs, int count,
                                     double *out)
{
    if (check_nargs(nargs, count, "configure") < 0) return -1;
    for (int k = 0; k < count; k++) {
        out[k] = PyFloat_AsDouble(args[k]);
        if (out[k] == -1.0 && PyErr_Occurred()) return -1;
        if (!(out[k] > 0.0 && isfinite(out[k]))) {
            PyErr_SetString(PyExc_ValueError, "configure: expected positive finite constants");
            return -1;
        }
    }
    return 0;
}

#endif
