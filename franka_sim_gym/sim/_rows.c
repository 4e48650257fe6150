/* sim/views.py ArmRows' loops over the robots (required, native.require: no switch; rows
 * that are not C-contiguous float64 views are copied by numpy instead):
 *
 *   scatter(values, targets, rows)
 *       targets[rows[k]] = values[k]: ``targets`` a tuple of C-contiguous float64 arrays
 *       of the values' row size, ``values`` C-contiguous float64 rows, ``rows`` an int64
 *       array of robot indices (None: every robot in order)
 *   Gathers(pairs)
 *       a gathering planned once: ``pairs`` a tuple of (sources, out), ``sources`` a
 *       tuple of n C-contiguous float64 arrays (robot i's rows of its own MjData) of
 *       out's row size, ``out`` a C-contiguous float64 array of n rows; it holds their
 *       buffers (the arrays stay alive and in place while it lives), and its
 *       ``gather()`` sets out[i] = sources[i] for every pair, in order, with no look-up
 *       per call (the rows of all the robots' MjData the cycle reads, in one call)
 *
 * Copies only, so the same bits as the numpy loops. No rule of the robot lives here. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "_arrays.h"

/* Borrow ``obj`` as a C-contiguous float64 buffer; 0 when it is one, else -1 with a
 * ValueError naming ``name``. */
static int float64_buffer(PyObject *obj, Py_buffer *view, int writable, const char *name)
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
    if (!f || strcmp(f, "d") != 0 || view->itemsize != 8) {
        PyErr_Format(PyExc_ValueError, "%s: expected a float64 array", name);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* Borrow ``obj`` as a C-contiguous float64 buffer of ``count`` doubles. */
static int contiguous(PyObject *obj, Py_buffer *view, Py_ssize_t count, int writable,
                      const char *name)
{
    if (float64_buffer(obj, view, writable, name) < 0) return -1;
    if (view->len != count * 8) {
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
    if (float64_buffer(obj, view, writable, name) < 0) return -1;
    if (view->ndim < 1) {
        PyErr_Format(PyExc_ValueError, "%s: expected a float64 array of rows", name);
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->shape[0];
    *size = *n ? view->len / 8 / *n : 0;
    return 0;
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

/* A planned gathering: every buffer held, every copy's pointers and size kept. */
typedef struct {
    PyObject_HEAD
    Py_ssize_t nbuffers; /* buffers held (each out and each source) */
    Py_buffer *buffers;
    Py_ssize_t ncopies;
    const double **src;
    double **dst;
    size_t *bytes;
} GathersObject;

static void Gathers_dealloc(GathersObject *self)
{
    for (Py_ssize_t k = 0; k < self->nbuffers; k++) PyBuffer_Release(&self->buffers[k]);
    PyMem_Free(self->buffers);
    PyMem_Free(self->src);
    PyMem_Free(self->dst);
    PyMem_Free(self->bytes);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *Gathers_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    PyObject *pairs;
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "Gathers() takes no keyword arguments");
        return NULL;
    }
    if (!PyArg_ParseTuple(args, "O!:Gathers", &PyTuple_Type, &pairs)) return NULL;
    Py_ssize_t npairs = PyTuple_GET_SIZE(pairs), ncopies = 0;
    for (Py_ssize_t p = 0; p < npairs; p++) {
        PyObject *pair = PyTuple_GET_ITEM(pairs, p);
        if (!PyTuple_Check(pair) || PyTuple_GET_SIZE(pair) != 2 ||
            !PyTuple_Check(PyTuple_GET_ITEM(pair, 0))) {
            PyErr_SetString(PyExc_TypeError, "Gathers: each pair must be (sources tuple, out)");
            return NULL;
        }
        ncopies += PyTuple_GET_SIZE(PyTuple_GET_ITEM(pair, 0));
    }
    GathersObject *self = (GathersObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->buffers = PyMem_Calloc((size_t)(ncopies + npairs) + 1, sizeof(Py_buffer));
    self->src = PyMem_Calloc((size_t)ncopies + 1, sizeof(double *));
    self->dst = PyMem_Calloc((size_t)ncopies + 1, sizeof(double *));
    self->bytes = PyMem_Calloc((size_t)ncopies + 1, sizeof(size_t));
    if (!self->buffers || !self->src || !self->dst || !self->bytes) {
        Py_DECREF(self);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t p = 0; p < npairs; p++) {
        PyObject *pair = PyTuple_GET_ITEM(pairs, p);
        PyObject *sources = PyTuple_GET_ITEM(pair, 0);
        Py_buffer *out = &self->buffers[self->nbuffers];
        Py_ssize_t n, size;
        if (row_shape(PyTuple_GET_ITEM(pair, 1), out, &n, &size, 1, "out") < 0) {
            Py_DECREF(self);
            return NULL;
        }
        self->nbuffers++;
        if (PyTuple_GET_SIZE(sources) != n) {
            PyErr_Format(PyExc_ValueError, "Gathers: %zd sources for %zd rows",
                         PyTuple_GET_SIZE(sources), n);
            Py_DECREF(self);
            return NULL;
        }
        for (Py_ssize_t i = 0; i < n; i++) {
            Py_buffer *src = &self->buffers[self->nbuffers];
            if (contiguous(PyTuple_GET_ITEM(sources, i), src, size, 0, "sources[i]") < 0) {
                Py_DECREF(self);
                return NULL;
            }
            self->nbuffers++;
            self->src[self->ncopies] = (const double *)src->buf;
            self->dst[self->ncopies] = (double *)out->buf + i * size;
            self->bytes[self->ncopies] = (size_t)size * 8;
            self->ncopies++;
        }
    }
    return (PyObject *)self;
}

static PyObject *Gathers_gather(GathersObject *self, PyObject *unused)
{
    (void)unused;
    for (Py_ssize_t k = 0; k < self->ncopies; k++)
        memcpy(self->dst[k], self->src[k], self->bytes[k]);
    Py_RETURN_NONE;
}

static PyMethodDef GATHERS_METHODS[] = {
    {"gather", (PyCFunction)Gathers_gather, METH_NOARGS,
     "Copy every pair's sources into its out (out[i] = sources[i])."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject GathersType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.sim._rows.Gathers",
    .tp_basicsize = sizeof(GathersObject),
    .tp_dealloc = (destructor)Gathers_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Gathers(pairs): the rows of (sources, out) pairs, copied by gather().",
    .tp_methods = GATHERS_METHODS,
    .tp_new = Gathers_new,
};

static PyMethodDef METHODS[] = {
    METHOD(scatter, "views.ArmRows.scatter's loop: targets[rows[k]] = values[k]."),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef _rows_definition = {
    PyModuleDef_HEAD_INIT, "_rows",
    "The loops over the robots' MjData rows (sim/views.py).", -1, METHODS,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__rows(void)
{
    if (PyType_Ready(&GathersType) < 0) return NULL;
    PyObject *m = kernel_module(&_rows_definition);
    if (!m) return NULL;
    Py_INCREF(&GathersType);
    if (PyModule_AddObject(m, "Gathers", (PyObject *)&GathersType) < 0) {
        Py_DECREF(&GathersType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
