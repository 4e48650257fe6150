/* The C replacement of sim/views.py ArmRows' loops over the robots, chosen by the backend
 * switch (native.load, views.py ROWS_KERNEL):
 *
 *   gather(sources, out)
 *       out[i] = sources[i] for each robot i: ``sources`` a tuple of n C-contiguous
 *       float64 arrays (robot i's rows of its own MjData) of out's row size, ``out`` a
 *       C-contiguous float64 array of n rows
 *   scatter(values, targets, rows)
 *       targets[rows[k]] = values[k]: ``targets`` a tuple of C-contiguous float64 arrays
 *       of the values' row size, ``values`` C-contiguous float64 rows, ``rows`` an int64
 *       array of robot indices (None: every robot in order)
 *
 * Copies only, so the same bits as the numpy loops. No rule of the robot lives here. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "_arrays.h"

/* Borrow ``obj`` as a C-contiguous float64 buffer of ``count`` doubles. */
static int contiguous(PyObject *obj, Py_buffer *view, Py_ssize_t count, int writable,
                      const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected a C-contiguous%s float64 array", name,
                     writable ? " writable" : "");
        return -1;
    }
    const char *f = view->format;
    if (f && (*f == '<' || *f == '=' || *f == '@')) f++;
    if (!f || strcmp(f, "d") != 0 || view->itemsize != 8 || view->len != count * 8) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd float64 values", name, count);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* Rows and row size of the C-contiguous float64 array ``obj``. */
static int row_shape(PyObject *obj, Py_buffer *view, Py_ssize_t *n, Py_ssize_t *size,
                     int writable, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: expected a C-contiguous%s float64 array", name,
                     writable ? " writable" : "");
        return -1;
    }
    const char *f = view->format;
    if (f && (*f == '<' || *f == '=' || *f == '@')) f++;
    if (!f || strcmp(f, "d") != 0 || view->itemsize != 8 || view->ndim < 1) {
        PyErr_Format(PyExc_ValueError, "%s: expected a float64 array of rows", name);
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->shape[0];
    *size = *n ? view->len / 8 / *n : 0;
    return 0;
}

static PyObject *gather(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 2, "gather") < 0) return NULL;
    if (!PyTuple_Check(args[0])) {
        PyErr_SetString(PyExc_TypeError, "gather: sources must be a tuple");
        return NULL;
    }
    Py_buffer out;
    Py_ssize_t n, size;
    if (row_shape(args[1], &out, &n, &size, 1, "out") < 0) return NULL;
    if (PyTuple_GET_SIZE(args[0]) != n) {
        PyErr_Format(PyExc_ValueError, "gather: %zd sources for %zd rows",
                     PyTuple_GET_SIZE(args[0]), n);
        PyBuffer_Release(&out);
        return NULL;
    }
    double *dst = (double *)out.buf;
    for (Py_ssize_t i = 0; i < n; i++) {
        Py_buffer src;
        if (contiguous(PyTuple_GET_ITEM(args[0], i), &src, size, 0, "sources[i]") < 0) {
            PyBuffer_Release(&out);
            return NULL;
        }
        memcpy(dst + i * size, src.buf, (size_t)size * 8);
        PyBuffer_Release(&src);
    }
    PyBuffer_Release(&out);
    return Py_NewRef(args[1]);
}

static PyObject *scatter(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (check_nargs(nargs, 3, "scatter") < 0) return NULL;
    if (!PyTuple_Check(args[1])) {
        PyErr_SetString(PyExc_TypeError, "scatter: targets must be a tuple");
        return NULL;
    }
    Py_buffer values, rows = {0};
    Py_ssize_t n, size, count = PyTuple_GET_SIZE(args[1]);
    if (row_shape(args[0], &values, &n, &size, 0, "values") < 0) return NULL;
    const long long *index = NULL;
    if (args[2] != Py_None) {
        if (PyObject_GetBuffer(args[2], &rows, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0 ||
            rows.itemsize != 8 || rows.len != n * 8 || !rows.format ||
            !(strchr("qlQL", rows.format[strlen(rows.format) - 1]))) {
            if (rows.obj) PyBuffer_Release(&rows);
            PyErr_Clear();
            PyErr_SetString(PyExc_ValueError, "scatter: rows must be an int64 array, one per value row");
            PyBuffer_Release(&values);
            return NULL;
        }
        index = (const long long *)rows.buf;
    } else if (n != count) {
        PyErr_Format(PyExc_ValueError, "scatter: %zd value rows for %zd targets", n, count);
        PyBuffer_Release(&values);
        return NULL;
    }
    const double *src = (const double *)values.buf;
    PyObject *result = Py_None;
    for (Py_ssize_t k = 0; k < n; k++) {
        Py_ssize_t i = index ? (Py_ssize_t)index[k] : k;
        if (i < 0 || i >= count) {
            PyErr_Format(PyExc_IndexError, "scatter: row %zd of %zd targets", i, count);
            result = NULL;
            break;
        }
        Py_buffer dst;
        if (contiguous(PyTuple_GET_ITEM(args[1], i), &dst, size, 1, "targets[i]") < 0) {
            result = NULL;
            break;
        }
        memcpy(dst.buf, src + k * size, (size_t)size * 8);
        PyBuffer_Release(&dst);
    }
    if (rows.obj) PyBuffer_Release(&rows);
    PyBuffer_Release(&values);
    return result ? Py_NewRef(result) : NULL;
}

static PyMethodDef METHODS[] = {
    METHOD(gather, "views.ArmRows.gather's loop: out[i] = sources[i]."),
    METHOD(scatter, "views.ArmRows.scatter's loop: targets[rows[k]] = values[k]."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_rows, "C replacement of the loops over the robots' MjData rows (sim/views.py).")
