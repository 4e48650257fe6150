/* What publishing state k+1 copies, fci/state.py StateWriter and fci/controller.py
 * FciController._publish_rest: its one text (issue 38), required (native.require):
 *
 *   Publishing(pose, pose_d, pose_c, elbow, elbow_d, elbow_c, q_d, shadow, states,
 *              message_id, layout)
 *       a plan over the state writer's float64 fields (O_T_EE, O_T_EE_d, O_T_EE_c (n, 16);
 *       elbow, elbow_d, elbow_c (n, 2); q_d (n, 7)), the float64
 *       shadow (n, F) of the wire's F float32 values, the (n,) RobotState array's bytes
 *       (states), the (n,) uint64 ids of the last published states (message_id) and the
 *       wire layout: (size, floats, id, success) -- a state's bytes, the first float's
 *       offset, the message id's and the success rate's;
 *   Publishing.pose(position, rotation, q)
 *       the measured pose and elbow: O_T_EE's translation from position (n, 3) and its
 *       rotation block (row r, column c of the wire's column-major 4 x 4 read as
 *       row-major) from rotation (n, 3, 3), the flange's rotation transposed (the bases
 *       at their worlds' origins); elbow = (q_3, the sign of q_4, sign(0) taken as +1 as
 *       copysign does: docs/fci-behaviour.md "RobotState fields") from q (n, 7);
 *   Publishing.copies(q, keeps_q_d)
 *       docs/fci-behaviour.md "RobotState fields": O_T_EE_d = O_T_EE_c = O_T_EE and
 *       elbow_d = elbow_c = elbow for every robot (a Cartesian generator then writes its
 *       own), q_d = q (the measured q (n, 7)) but for the robots whose q_d is a reference
 *       ((n,) bool: a joint generator's or an external controller's motion): between
 *       motions and during a Cartesian one;
 *   Publishing.publish(success_rate)
 *       every robot's next message id, the shadow cast to the wire's float32 (round to
 *       nearest, as numpy's cast), and the success rate ((n,) float64, or None: kept).
 *
 * A wire record is 1377 bytes, so its fields sit at any alignment: they are written with
 * memcpy, little-endian as the wire (the build targets little-endian hosts only, as
 * numpy's "<f4" view did). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_arrays.h"

enum { P_POSE, P_POSE_D, P_POSE_C, P_ELBOW, P_ELBOW_D, P_ELBOW_C, P_Q_D, P_SHADOW, P_F64 };

typedef struct {
    PyObject_HEAD
    Py_ssize_t n, floats;        /* robots; float32 values of a state */
    F64 a[P_F64];
    Py_buffer states;            /* the (n,) RobotState array's bytes */
    Int64s message_id;           /* (n,) uint64 */
    Py_ssize_t size, first, id, success; /* the layout's byte sizes and offsets */
    float *cast;                 /* one state's floats, cast before their one memcpy */
} PublishingObject;

static void Publishing_dealloc(PublishingObject *self)
{
    f64_release_all(self->a, P_F64);
    if (self->states.obj) PyBuffer_Release(&self->states);
    int64s_release(&self->message_id);
    PyMem_Free(self->cast);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static const char *const NAMES[P_F64] = {"pose",    "pose_d", "pose_c", "elbow", "elbow_d",
                                         "elbow_c", "q_d",    "shadow"};

static PyObject *Publishing_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "Publishing() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 11, "Publishing") < 0) return NULL;
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    Py_ssize_t n = leading(v[P_POSE], "pose");
    if (n < 0) return NULL;
    PublishingObject *self = (PublishingObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    Py_ssize_t s16[2] = {n, 16}, s2[2] = {n, 2}, s7[2] = {n, 7}, sf[2] = {n, -1};
    const Py_ssize_t *shapes[P_F64] = {s16, s16, s16, s2, s2, s2, s7, sf};
    for (int k = 0; k < P_F64; k++) {
        int writable = k != P_SHADOW;
        if (f64_get(v[k], &self->a[k], 2, shapes[k], writable, NAMES[k]) < 0) goto fail;
    }
    self->floats = self->a[P_SHADOW].shape[1];
    if (self->a[P_SHADOW].strides[1] != 8) {
        PyErr_SetString(PyExc_ValueError, "shadow: expected rows of contiguous float64");
        goto fail;
    }
    if (!(self->cast = PyMem_Malloc(sizeof(float) * (size_t)(self->floats + 1)))) {
        PyErr_NoMemory();
        goto fail;
    }
    if (int64s_get(v[9], &self->message_id, n, 1, "message_id") < 0) goto fail;
    PyObject *layout = v[10];
    if (!PyTuple_Check(layout) || PyTuple_GET_SIZE(layout) != 4) {
        PyErr_SetString(PyExc_TypeError, "layout: expected (size, floats, id, success)");
        goto fail;
    }
    Py_ssize_t at[4];
    for (int k = 0; k < 4; k++) {
        at[k] = PyLong_AsSsize_t(PyTuple_GET_ITEM(layout, k));
        if (at[k] == -1 && PyErr_Occurred()) goto fail;
    }
    self->size = at[0], self->first = at[1], self->id = at[2], self->success = at[3];
    if (self->first < 0 || self->first + 4 * self->floats > self->size || self->id < 0 ||
        self->id + 8 > self->size || self->success < 0 || self->success + 4 > self->size) {
        PyErr_Format(PyExc_ValueError,
                     "layout: %zd floats at %zd, the id at %zd and the success rate at %zd "
                     "do not fit a %zd-byte state",
                     self->floats, self->first, self->id, self->success, self->size);
        goto fail;
    }
    if (PyObject_GetBuffer(v[8], &self->states, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0) {
        PyErr_Clear();
        PyErr_SetString(PyExc_ValueError, "states: expected a writable C-contiguous array");
        goto fail;
    }
    if (self->states.len != n * self->size) {
        PyErr_Format(PyExc_ValueError, "states: %zd bytes, expected %zd states of %zd",
                     self->states.len, n, self->size);
        goto fail;
    }
    return (PyObject *)self;
fail:
    Py_DECREF(self);
    return NULL;
}

static PyObject *Publishing_pose(PublishingObject *self, PyObject *const *args,
                                 Py_ssize_t nargs)
{
    if (check_nargs(nargs, 3, "pose") < 0) return NULL;
    Py_ssize_t n = self->n, s3[2] = {n, 3}, s33[3] = {n, 3, 3}, s7[2] = {n, 7};
    F64 position, rotation, q;
    memset(&position, 0, sizeof(position));
    memset(&rotation, 0, sizeof(rotation));
    memset(&q, 0, sizeof(q));
    PyObject *result = NULL;
    if (f64_get(args[0], &position, 2, s3, 0, "position") < 0 ||
        f64_get(args[1], &rotation, 3, s33, 0, "rotation") < 0 ||
        f64_get(args[2], &q, 2, s7, 0, "q") < 0)
        goto done;
    F64 *a = self->a;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int r = 0; r < 3; r++) {
            AT2(a[P_POSE], i, 12 + r) = AT2(position, i, r);
            for (int c = 0; c < 3; c++) AT2(a[P_POSE], i, 4 * r + c) = AT3(rotation, i, r, c);
        }
        AT2(a[P_ELBOW], i, 0) = AT2(q, i, 2);
        AT2(a[P_ELBOW], i, 1) = copysign(1.0, AT2(q, i, 3));
    }
    result = Py_NewRef(Py_None);
done:
    f64_release(&position);
    f64_release(&rotation);
    f64_release(&q);
    return result;
}

static PyObject *Publishing_copies(PublishingObject *self, PyObject *const *args,
                                   Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "copies") < 0) return NULL;
    Py_ssize_t s7[2] = {self->n, 7};
    F64 q;
    Bytes motion;
    if (f64_get(args[0], &q, 2, s7, 0, "q") < 0) return NULL;
    if (bytes_get(args[1], &motion, self->n, 0, "keeps_q_d") < 0) {
        f64_release(&q);
        return NULL;
    }
    F64 *a = self->a;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        for (int k = 0; k < 16; k++) {
            double x = AT2(a[P_POSE], i, k);
            AT2(a[P_POSE_D], i, k) = x;
            AT2(a[P_POSE_C], i, k) = x;
        }
        for (int k = 0; k < 2; k++) {
            double x = AT2(a[P_ELBOW], i, k);
            AT2(a[P_ELBOW_D], i, k) = x;
            AT2(a[P_ELBOW_C], i, k) = x;
        }
        if (!BYTE1(motion, i)) /* between motions and in a Cartesian one: the measured q */
            for (int j = 0; j < 7; j++) AT2(a[P_Q_D], i, j) = AT2(q, i, j);
    }
    f64_release(&q);
    bytes_release(&motion);
    Py_RETURN_NONE;
}

static PyObject *Publishing_publish(PublishingObject *self, PyObject *success_rate)
{
    F64 rate;
    memset(&rate, 0, sizeof(rate));
    int with_rate = success_rate != Py_None;
    Py_ssize_t sn[1] = {self->n};
    if (with_rate && f64_get(success_rate, &rate, 1, sn, 0, "success_rate") < 0) return NULL;
    char *base = self->states.buf;
    const F64 *shadow = &self->a[P_SHADOW];
    for (Py_ssize_t i = 0; i < self->n; i++) {
        char *state = base + i * self->size;
        uint64_t id = (uint64_t)INT64_AT(self->message_id, i) + 1;
        INT64_AT(self->message_id, i) = (long long)id;
        memcpy(state + self->id, &id, 8);
        const double *row = (const double *)(shadow->data + i * shadow->strides[0]);
        float *cast = self->cast;
        Py_ssize_t k = 0, floats = self->floats;
        for (; k + 8 <= floats; k += 8) /* blocks of a fixed size: the compiler vectorizes */
            for (int b = 0; b < 8; b++) cast[k + b] = (float)row[k + b];
        for (; k < floats; k++) cast[k] = (float)row[k];
        memcpy(state + self->first, cast, sizeof(float) * (size_t)self->floats);
        if (with_rate) {
            float x = (float)AT1(rate, i);
            memcpy(state + self->success, &x, 4);
        }
    }
    f64_release(&rate);
    Py_RETURN_NONE;
}

static PyMethodDef PUBLISHING_METHODS[] = {
    {"pose", (PyCFunction)(void (*)(void))Publishing_pose, METH_FASTCALL,
     "pose(position, rotation, q): the measured O_T_EE and elbow."},
    {"copies", (PyCFunction)(void (*)(void))Publishing_copies, METH_FASTCALL,
     "copies(q, keeps_q_d): the desired and commanded pose and elbow, and q_d = q where no "
     "reference is kept."},
    {"publish", (PyCFunction)Publishing_publish, METH_O,
     "publish(success_rate): the next message ids, the shadow cast to the wire, the rate."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject PublishingType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.fci._publish.Publishing",
    .tp_basicsize = sizeof(PublishingObject),
    .tp_dealloc = (destructor)Publishing_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Publishing(pose, pose_d, pose_c, elbow, elbow_d, elbow_c, q_d, shadow, "
              "states, message_id, layout): what publishing a state copies.",
    .tp_methods = PUBLISHING_METHODS,
    .tp_new = Publishing_new,
};

static struct PyModuleDef _publish_definition = {
    PyModuleDef_HEAD_INIT, "_publish", "What publishing a RobotState copies.", -1, NULL,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__publish(void)
{
    if (PyType_Ready(&PublishingType) < 0) return NULL;
    PyObject *m = kernel_module(&_publish_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "Publishing", (PyObject *)&PublishingType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
