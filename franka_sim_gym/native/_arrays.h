/* What every C kernel shares (franka_sim_gym/<layer>/_<name>.c, built by setup.py):
 * float64 (and float32) array arguments through the buffer protocol, strided (views of
 * structured state fields and of stacked scratch rows are fine), with their shape checked
 * before a single element is read or written; (n,) one-byte flags (uint8 or numpy's bool);
 * (n,) 8-byte integers; the argument count; numpy's minimum / maximum; the module. No rule
 * of the robot lives here. */
#ifndef FRANKA_SIM_GYM_NATIVE_ARRAYS_H
#define FRANKA_SIM_GYM_NATIVE_ARRAYS_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

typedef struct {
    Py_buffer view;
    char *data;
    int ndim;
    Py_ssize_t shape[4];
    Py_ssize_t strides[4];
    char kind; /* 'd' (float64) or, through num_get, 'f' (float32) */
} F64;

/* Element access: 1-, 2- and 3-D. */
#define AT1(a, i) (*(double *)((a).data + (i) * (a).strides[0]))
#define AT2(a, i, j) (*(double *)((a).data + (i) * (a).strides[0] + (j) * (a).strides[1]))
#define AT3(a, i, j, k)                                                                  \
    (*(double *)((a).data + (i) * (a).strides[0] + (j) * (a).strides[1] +               \
                 (k) * (a).strides[2]))

/* Borrow ``obj`` as a float64 array of ``ndim`` axes; ``shape[k]`` < 0 accepts any
 * length on axis k. Returns 0, or -1 with a ValueError naming ``name``. */
static inline int borrow(PyObject *obj, F64 *a, int ndim, const Py_ssize_t *shape, int writable,
                  const char *name, int float32_too);

static inline int f64_get(PyObject *obj, F64 *a, int ndim, const Py_ssize_t *shape, int writable,
                   const char *name)
{
    return borrow(obj, a, ndim, shape, writable, name, 0);
}

/* As f64_get, and float32 accepted too (the wire state's fields); read such arrays with
 * num2 / put2, which also allow the wire's unaligned (packed) records. */
static inline int num_get(PyObject *obj, F64 *a, int ndim, const Py_ssize_t *shape, int writable,
                   const char *name)
{
    return borrow(obj, a, ndim, shape, writable, name, 1);
}

static inline int borrow(PyObject *obj, F64 *a, int ndim, const Py_ssize_t *shape, int writable,
                  const char *name, int float32_too)
{
    int flags = PyBUF_RECORDS_RO | (writable ? PyBUF_WRITABLE : 0);
    memset(a, 0, sizeof(*a));
    if (PyObject_GetBuffer(obj, &a->view, flags) < 0) {
        PyErr_Format(PyExc_ValueError, "%s: expected a%s float64 array", name,
                     writable ? " writable" : "");
        return -1;
    }
    const char *f = a->view.format;
    if (f && (*f == '<' || *f == '=' || *f == '@')) f++;
    int is_f8 = f && strcmp(f, "d") == 0 && a->view.itemsize == 8;
    int is_f4 = float32_too && f && strcmp(f, "f") == 0 && a->view.itemsize == 4;
    if (a->view.ndim != ndim || !(is_f8 || is_f4)) {
        PyErr_Format(PyExc_ValueError, "%s: expected a %d-D float64%s array", name, ndim,
                     float32_too ? " or float32" : "");
        PyBuffer_Release(&a->view);
        a->view.obj = NULL;
        return -1;
    }
    for (int k = 0; k < ndim; k++) {
        if (shape[k] >= 0 && a->view.shape[k] != shape[k]) {
            PyErr_Format(PyExc_ValueError, "%s: axis %d has length %zd, expected %zd", name,
                         k, a->view.shape[k], shape[k]);
            PyBuffer_Release(&a->view);
            a->view.obj = NULL;
            return -1;
        }
        a->shape[k] = a->view.shape[k];
        a->strides[k] = a->view.strides ? a->view.strides[k] : 8;
    }
    a->data = (char *)a->view.buf;
    a->ndim = ndim;
    a->kind = is_f8 ? 'd' : 'f';
    return 0;
}

/* Element (i, j) of a num_get array as a double (float32 widened exactly). */
static inline double num2(const F64 *a, Py_ssize_t i, Py_ssize_t j)
{
    const char *p = a->data + i * a->strides[0] + j * a->strides[1];
    if (a->kind == 'd') {
        double v;
        memcpy(&v, p, 8);
        return v;
    }
    float v;
    memcpy(&v, p, 4);
    return (double)v;
}

/* Store into element (i, j) of a writable float64 num_get array (any alignment). */
static inline void put2(const F64 *a, Py_ssize_t i, Py_ssize_t j, double v)
{
    memcpy(a->data + i * a->strides[0] + j * a->strides[1], &v, 8);
}

static inline void f64_release(F64 *a)
{
    if (a->view.obj) PyBuffer_Release(&a->view);
    a->view.obj = NULL;
}

/* An (n,) array of one-byte flags (uint8 or numpy's bool), or None where the caller allows
 * it (data NULL). */
typedef struct {
    Py_buffer view;
    char *data;
    Py_ssize_t stride;
} Bytes;

#define BYTE1(b, i) (*(unsigned char *)((b).data + (i) * (b).stride))

/* Borrow ``obj`` as (n,) one-byte flags, uint8 or bool, writable where asked (a kernel
 * writes 0 or 1, which both read alike). Returns 0, or -1 with a ValueError naming
 * ``name``. */
static inline int bytes_get(PyObject *obj, Bytes *b, Py_ssize_t n, int writable, const char *name)
{
    memset(b, 0, sizeof(*b));
    const char *kind = writable ? " writable" : "";
    int flags = PyBUF_RECORDS_RO | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected a%s uint8 or bool array", name, kind);
        return -1;
    }
    const char *f = b->view.format;
    if (f && (*f == '<' || *f == '=' || *f == '@' || *f == '|')) f++;
    int kind_ok = f && (strcmp(f, "B") == 0 || strcmp(f, "?") == 0);
    if (b->view.ndim != 1 || b->view.itemsize != 1 || !kind_ok || b->view.shape[0] != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected a%s uint8 or bool array of shape (%zd,)",
                     name, kind, n);
        PyBuffer_Release(&b->view);
        b->view.obj = NULL;
        return -1;
    }
    b->data = (char *)b->view.buf;
    b->stride = b->view.strides ? b->view.strides[0] : 1;
    return 0;
}

/* As bytes_get, and None accepted (no array: data NULL). */
static inline int bytes_or_none_get(PyObject *obj, Bytes *b, Py_ssize_t n, int writable,
                                    const char *name)
{
    if (obj == Py_None) {
        memset(b, 0, sizeof(*b));
        return 0;
    }
    return bytes_get(obj, b, n, writable, name);
}

static inline void bytes_release(Bytes *b)
{
    if (b->view.obj) PyBuffer_Release(&b->view);
    b->view.obj = NULL;
}

/* An (n,) array of 8-byte integers (int64 or uint64: message ids, counters), read and
 * written as their 8 bytes. */
typedef struct {
    Py_buffer view;
    char *data;
    Py_ssize_t stride;
} Int64s;

#define INT64_AT(b, i) (*(long long *)((b).data + (i) * (b).stride))

/* Borrow ``obj`` as (n,) 8-byte integers. Returns 0, or -1 with a ValueError naming
 * ``name``. */
static inline int int64s_get(PyObject *obj, Int64s *b, Py_ssize_t n, int writable,
                             const char *name)
{
    memset(b, 0, sizeof(*b));
    int flags = PyBUF_RECORDS_RO | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected a%s int64 array", name,
                     writable ? " writable" : "");
        return -1;
    }
    const char *f = b->view.format;
    if (f && (*f == '<' || *f == '=' || *f == '@')) f++;
    int kind_ok = f && f[0] && !f[1] && strchr("qQlL", f[0]);
    if (b->view.ndim != 1 || b->view.itemsize != 8 || !kind_ok || b->view.shape[0] != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected an int64 or uint64 array of shape (%zd,)",
                     name, n);
        PyBuffer_Release(&b->view);
        b->view.obj = NULL;
        return -1;
    }
    b->data = (char *)b->view.buf;
    b->stride = b->view.strides ? b->view.strides[0] : 8;
    return 0;
}

static inline void int64s_release(Int64s *b)
{
    if (b->view.obj) PyBuffer_Release(&b->view);
    b->view.obj = NULL;
}

/* A helper that must be inlined into its loop: a rule's per-joint rows return their terms
 * through a pointer the loop passes as NULL, which only inlining turns into no stores
 * (measured: 112 against 73 ns an arm for the joint rules at 64 arms without it). */
#if defined(__GNUC__) || defined(__clang__)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE inline
#endif

/* A kernel module. (Every constant a rule needs, the cycle among them, is passed in by its
 * caller: fci/tables.py DELTA_T is the cycle's one definition.) */
static inline PyObject *kernel_module(PyModuleDef *def) { return PyModule_Create(def); }

/* One METH_FASTCALL entry of a kernel module's METHODS table. */
#define METHOD(name, doc) {#name, (PyCFunction)(void (*)(void))name, METH_FASTCALL, doc}

/* The definition and the init function of kernel module ``name`` (an identifier such as
 * _client_filters: PyInit__client_filters) with its ``doc`` and METHODS table. */
#define KERNEL_MODULE(name, doc)                                                         \
    static struct PyModuleDef name##_definition = {                                      \
        PyModuleDef_HEAD_INIT, #name, doc, -1, METHODS, NULL, NULL, NULL, NULL};        \
    PyMODINIT_FUNC PyInit_##name(void) { return kernel_module(&name##_definition); }

/* numpy's minimum / maximum on non-NaN values (the kernels' inputs are finite). */
static inline double np_minimum(double a, double b) { return a <= b ? a : b; }
static inline double np_maximum(double a, double b) { return a >= b ? a : b; }

/* Release every array of a call (those never borrowed are skipped). */
static inline void f64_release_all(F64 *arrays, int count)
{
    for (int k = 0; k < count; k++) f64_release(&arrays[k]);
}

/* A kernel's argument count. */
static inline int check_nargs(Py_ssize_t nargs, Py_ssize_t expected, const char *name)
{
    if (nargs == expected) return 0;
    PyErr_Format(PyExc_TypeError, "%s() takes %zd arguments (%zd given)", name, expected, nargs);
    return -1;
}

/* The length of the first axis of the array ``obj`` (the others' shapes follow it). */
static inline Py_ssize_t leading(PyObject *obj, const char *name)
{
    Py_buffer view;
    if (PyObject_GetBuffer(obj, &view, PyBUF_RECORDS_RO) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected an array", name);
        return -1;
    }
    Py_ssize_t n = view.ndim >= 1 ? view.shape[0] : -1;
    PyBuffer_Release(&view);
    if (n < 0) PyErr_Format(PyExc_ValueError, "%s: expected an array of 1 or more axes", name);
    return n;
}

#endif
