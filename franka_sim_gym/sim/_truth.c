/* The true arm's per-cycle joint torques under a reality draw: their one text (issue 38:
 * the rules the cycle runs, compiled; docs/reality.md). sim/friction.py JointFriction and
 * sim/truth.py LinkWeights / ArmTruth call it with their arrays (all (n, 7) per robot and
 * joint unless said):
 *
 *   friction(dq, gain, half_alpha, shift, out)
 *       Gaz et al.'s friction law (sim/friction.py) written with tanh:
 *       out = (tanh(dq half_alpha + shift) - tanh(shift)) gain, with half_alpha = alpha / 2,
 *       shift = half_alpha phi and gain = scale A / 2 (the sign: against the motion in the
 *       drives, with it in the robot's compensation); exactly zero at rest;
 *   link_weights(xmat, dmc, dm, tail, origins, axes, out)
 *       dg_j = (z_j x sum_{i >= j} [R_i d(mc)_i + dm_i p_i - dm_i p_j])_z, the gravity
 *       torque of the links' differences from the model (sim/truth.py LinkWeights):
 *       xmat (n, 7, 9) the links' rotations (row-major), dmc (n, 7, 3) G d(mc), dm and
 *       tail (n, 7, 1) G dm_i and G sum_{i >= j} dm_i, origins and axes (n, 7, 3) the
 *       joints' anchors and unit axes;
 *   Forces(dq, gain, half_alpha, shift, xmat, dmc, dm, tail, origins, axes, targets)
 *       friction - link_weights planned once (ArmTruth): ``targets`` a tuple of n
 *       C-contiguous float64 arrays of 7 (robot i's qfrc_applied rows in its own MjData);
 *       it holds every buffer (the arrays stay alive and in place while it lives: their
 *       values change, not their memory), and its ``apply()`` writes robot i's extra joint
 *       forces of a step into targets[i] with no look-up per call;
 *   Friction(dq, gain, half_alpha, shift, out)
 *       the friction law planned once at the velocity array ``dq`` (the robot's
 *       compensation at its measured velocity, fci/reality/): ``torque()`` fills and
 *       returns ``out``.
 *
 * Sums run in the order the numpy texts they replaced ran them (R d(mc) as numpy's einsum
 * sums three products, (x0 y0 + x2 y2) + x1 y1; the tail sums from the last link down),
 * built without fused multiply-adds (setup.py). tanh is libm's, where numpy's own SIMD tanh
 * may round an ulp apart: a reality draw's states moved by that rounding when these rules
 * came to C (docs/architecture.md), and the law's value at rest, tanh(shift) - tanh(shift),
 * became exactly zero again (the numpy text's was, with numpy's tanh on both sides). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_arrays.h"

enum { DQ, GAIN, HALF_ALPHA, SHIFT, FRICTION_ARGS };
enum { XMAT, DMC, DM, TAIL, ORIGINS, AXES, WEIGHT_ARGS };

/* Borrow the friction law's four (n, 7) arrays from args[0..3]. */
static int get_friction(PyObject *const *args, F64 *a, Py_ssize_t n)
{
    static const char *names[FRICTION_ARGS] = {"dq", "gain", "half_alpha", "shift"};
    Py_ssize_t s7[2] = {n, 7};
    for (int k = 0; k < FRICTION_ARGS; k++)
        if (f64_get(args[k], &a[k], 2, s7, 0, names[k]) < 0) return -1;
    return 0;
}

/* Borrow the link weights' six arrays from args[0..5]. */
static int get_weights(PyObject *const *args, F64 *a, Py_ssize_t n)
{
    Py_ssize_t s79[3] = {n, 7, 9}, s73[3] = {n, 7, 3}, s71[3] = {n, 7, 1};
    return (f64_get(args[0], &a[XMAT], 3, s79, 0, "xmat") < 0 ||
            f64_get(args[1], &a[DMC], 3, s73, 0, "dmc") < 0 ||
            f64_get(args[2], &a[DM], 3, s71, 0, "dm") < 0 ||
            f64_get(args[3], &a[TAIL], 3, s71, 0, "tail") < 0 ||
            f64_get(args[4], &a[ORIGINS], 3, s73, 0, "origins") < 0 ||
            f64_get(args[5], &a[AXES], 3, s73, 0, "axes") < 0)
               ? -1
               : 0;
}

static inline double friction_at(const F64 *a, Py_ssize_t i, int j)
{
    double shift = AT2(a[SHIFT], i, j);
    double x = AT2(a[DQ], i, j) * AT2(a[HALF_ALPHA], i, j) + shift;
    return (tanh(x) - tanh(shift)) * AT2(a[GAIN], i, j);
}

/* Robot i's dg (7 values) into dg. */
static void weights_of(const F64 *a, Py_ssize_t i, double dg[7])
{
    double w[7][3], sums[7][3];
    for (int k = 0; k < 7; k++) {
        double c[3] = {AT3(a[DMC], i, k, 0), AT3(a[DMC], i, k, 1), AT3(a[DMC], i, k, 2)};
        double dm = AT3(a[DM], i, k, 0);
        for (int r = 0; r < 3; r++) {
            double R0 = AT3(a[XMAT], i, k, 3 * r), R1 = AT3(a[XMAT], i, k, 3 * r + 1);
            double R2 = AT3(a[XMAT], i, k, 3 * r + 2);
            w[k][r] = ((R0 * c[0] + R2 * c[2]) + R1 * c[1]) + AT3(a[ORIGINS], i, k, r) * dm;
        }
    }
    for (int r = 0; r < 3; r++) {
        sums[6][r] = w[6][r];
        for (int k = 5; k >= 0; k--) sums[k][r] = sums[k + 1][r] + w[k][r];
    }
    for (int k = 0; k < 7; k++) {
        double tail = AT3(a[TAIL], i, k, 0);
        double v0 = sums[k][0] - AT3(a[ORIGINS], i, k, 0) * tail;
        double v1 = sums[k][1] - AT3(a[ORIGINS], i, k, 1) * tail;
        dg[k] = v1 * AT3(a[AXES], i, k, 0) - v0 * AT3(a[AXES], i, k, 1);
    }
}

/* The free functions' common shape: the law or the weights (one of them), their arguments
 * from args, out last. */
static PyObject *run(PyObject *const *args, Py_ssize_t nargs, int with_friction,
                     int with_weights, const char *name)
{
    int count = (with_friction ? FRICTION_ARGS : 0) + (with_weights ? WEIGHT_ARGS : 0);
    F64 f[FRICTION_ARGS], w[WEIGHT_ARGS], out;
    memset(f, 0, sizeof(f));
    memset(w, 0, sizeof(w));
    memset(&out, 0, sizeof(out));
    PyObject *result = NULL;
    if (check_nargs(nargs, count + 1, name) < 0) return NULL;
    Py_ssize_t n = leading(args[count], "out");
    if (n < 0) return NULL;
    Py_ssize_t s7[2] = {n, 7};
    if ((with_friction && get_friction(args, f, n) < 0) ||
        (with_weights && get_weights(args + (with_friction ? FRICTION_ARGS : 0), w, n) < 0) ||
        f64_get(args[count], &out, 2, s7, 1, "out") < 0)
        goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        double dg[7] = {0};
        if (with_weights) weights_of(w, i, dg);
        for (int j = 0; j < 7; j++) AT2(out, i, j) = with_friction ? friction_at(f, i, j) : dg[j];
    }
    result = Py_NewRef(out.view.obj);
done:
    f64_release_all(f, FRICTION_ARGS);
    f64_release_all(w, WEIGHT_ARGS);
    f64_release(&out);
    return result;
}

static PyObject *friction(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return run(args, nargs, 1, 0, "friction");
}

static PyObject *link_weights(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    return run(args, nargs, 0, 1, "link_weights");
}

/* A planned call: the law's arrays (and the weights' with ``weights``) held, where it
 * writes (``out``, or robot i's 7 values at targets[i]). */
typedef struct {
    PyObject_HEAD
    int weights;
    Py_ssize_t n;
    F64 f[FRICTION_ARGS], w[WEIGHT_ARGS], out;
    Py_buffer *held; /* the targets' buffers (n of them; NULL with out) */
    Py_ssize_t nheld;
} PlanObject;

static void Plan_dealloc(PlanObject *self)
{
    f64_release_all(self->f, FRICTION_ARGS);
    f64_release_all(self->w, WEIGHT_ARGS);
    f64_release(&self->out);
    for (Py_ssize_t k = 0; k < self->nheld; k++) PyBuffer_Release(&self->held[k]);
    PyMem_Free(self->held);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* A plan of ``type`` from ``args``: the law's four arrays, the weights' six with
 * ``weights``, then the targets tuple (``weights``) or out. */
static PyObject *plan_new(PyTypeObject *type, PyObject *args, PyObject *kwargs, int weights,
                          const char *name)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_Format(PyExc_TypeError, "%s() takes no keyword arguments", name);
        return NULL;
    }
    Py_ssize_t count = FRICTION_ARGS + (weights ? WEIGHT_ARGS : 0);
    if (check_nargs(PyTuple_GET_SIZE(args), count + 1, name) < 0) return NULL;
    PyObject *const *a = &PyTuple_GET_ITEM(args, 0);
    PyObject *last = a[count];
    Py_ssize_t n;
    if (weights) {
        if (!PyTuple_Check(last)) {
            PyErr_Format(PyExc_TypeError, "%s: targets must be a tuple", name);
            return NULL;
        }
        n = PyTuple_GET_SIZE(last);
    } else if ((n = leading(last, "out")) < 0) {
        return NULL;
    }
    PlanObject *self = (PlanObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->weights = weights;
    self->n = n;
    Py_ssize_t s7[2] = {n, 7};
    if (get_friction(a, self->f, n) < 0 ||
        (weights && get_weights(a + FRICTION_ARGS, self->w, n) < 0) ||
        (!weights && f64_get(last, &self->out, 2, s7, 1, "out") < 0)) {
        Py_DECREF(self);
        return NULL;
    }
    if (weights) {
        self->held = PyMem_Calloc((size_t)n + 1, sizeof(Py_buffer));
        if (!self->held) {
            Py_DECREF(self);
            return PyErr_NoMemory();
        }
        for (Py_ssize_t i = 0; i < n; i++) {
            Py_buffer *view = &self->held[i];
            int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE;
            if (PyObject_GetBuffer(PyTuple_GET_ITEM(last, i), view, flags) < 0) {
                PyErr_Clear();
                PyErr_Format(PyExc_ValueError,
                             "targets[%zd]: expected a C-contiguous writable float64 array", i);
                Py_DECREF(self);
                return NULL;
            }
            self->nheld++;
            const char *f = view->format;
            if (f && (*f == '<' || *f == '=' || *f == '@')) f++;
            if (!f || strcmp(f, "d") != 0 || view->len != 7 * 8) {
                PyErr_Format(PyExc_ValueError, "targets[%zd]: expected 7 float64 values", i);
                Py_DECREF(self);
                return NULL;
            }
        }
    }
    return (PyObject *)self;
}

static PyObject *Forces_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    return plan_new(type, args, kwargs, 1, "Forces");
}

static PyObject *Friction_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    return plan_new(type, args, kwargs, 0, "Friction");
}

static PyObject *Forces_apply(PlanObject *self, PyObject *unused)
{
    (void)unused;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        double dg[7], *target = (double *)self->held[i].buf;
        weights_of(self->w, i, dg);
        for (int j = 0; j < 7; j++) target[j] = friction_at(self->f, i, j) - dg[j];
    }
    Py_RETURN_NONE;
}

static PyObject *Friction_torque(PlanObject *self, PyObject *unused)
{
    (void)unused;
    for (Py_ssize_t i = 0; i < self->n; i++)
        for (int j = 0; j < 7; j++) AT2(self->out, i, j) = friction_at(self->f, i, j);
    return Py_NewRef(self->out.view.obj);
}

static PyMethodDef FORCES_METHODS[] = {
    {"apply", (PyCFunction)Forces_apply, METH_NOARGS,
     "Write friction - dg, robot i's extra joint forces of a step, into targets[i]."},
    {NULL, NULL, 0, NULL},
};

static PyMethodDef FRICTION_METHODS[] = {
    {"torque", (PyCFunction)Friction_torque, METH_NOARGS,
     "The law at the planned dq into out; returns out."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject ForcesType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.sim._truth.Forces",
    .tp_basicsize = sizeof(PlanObject),
    .tp_dealloc = (destructor)Plan_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Forces(dq, gain, half_alpha, shift, xmat, dmc, dm, tail, origins, axes, "
              "targets): a step's extra joint forces, written by apply().",
    .tp_methods = FORCES_METHODS,
    .tp_new = Forces_new,
};

static PyTypeObject FrictionType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.sim._truth.Friction",
    .tp_basicsize = sizeof(PlanObject),
    .tp_dealloc = (destructor)Plan_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Friction(dq, gain, half_alpha, shift, out): the law at dq, by torque().",
    .tp_methods = FRICTION_METHODS,
    .tp_new = Friction_new,
};

static PyMethodDef METHODS[] = {
    METHOD(friction, "friction(dq, gain, half_alpha, shift, out): Gaz et al.'s law."),
    METHOD(link_weights, "link_weights(xmat, dmc, dm, tail, origins, axes, out): dg(q)."),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef _truth_definition = {
    PyModuleDef_HEAD_INIT, "_truth", "The true arm's per-cycle joint torques under a reality draw.",
    -1, METHODS, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__truth(void)
{
    if (PyType_Ready(&ForcesType) < 0 || PyType_Ready(&FrictionType) < 0) return NULL;
    PyObject *m = kernel_module(&_truth_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "Forces", (PyObject *)&ForcesType) < 0 ||
        PyModule_AddObjectRef(m, "Friction", (PyObject *)&FrictionType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
