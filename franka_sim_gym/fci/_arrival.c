/* Which arriving commands a cycle takes, and what it keeps of them: fci/arrival.py's rules,
 * their only text (issue 38), required (native.require).
 *
 *   Arrival(robot_mode, generator, controller, published, first_id,
 *           answered, started, have, finish, refused, refused_elbow, refused_torque,
 *           q_c, dq_c, tau_c, T_cmd, twist_cmd, elbow_cmd, elbow_valid,
 *           late, accepted, unanswerable, reason, layout, modes, tol)
 *       a plan over the controller's arrays, each (n,) per robot or (n, ...) rows:
 *       the modes (uint8, read), the ids of the last published states and of each
 *       motion's first (8-byte, read); the accounting's answered and started, the
 *       cycle input's flags (bool, written); the candidates the generators read
 *       (float64 rows, written: q_c, dq_c, tau_c (n, 7), T_cmd (n, 4, 4) row-major,
 *       twist_cmd (n, 6), elbow_cmd (n, 2), and elbow_valid (n,) bool); the outputs of
 *       ``arrive`` (late, accepted, unanswerable (n,) bool, reason (n,) uint8); the
 *       RobotCommand record's layout: (size, then the byte offsets of message_id, q_c,
 *       dq_c, O_T_EE_c, O_dP_EE_c, elbow_c, valid_elbow, motion_generation_finished,
 *       tau_J_d, torque_command_finished); the mode values (RobotMode kMove, then the
 *       generators kJointPosition, kJointVelocity, kCartesianPosition,
 *       kCartesianVelocity, kNone, then the controller kExternalController); and
 *       isHomogeneousTransformation's tolerance;
 *
 *   Arrival.arrive(commands, mask) -> code
 *       classifies the commands delivered where ``mask`` to robots in motion
 *       (docs/fci-behaviour.md "The cycle contract"): one echoing the id of the last
 *       published state is fresh and answers the cycle (``answered``); an older id of
 *       the running motion is late, and still applied; any other answers nothing
 *       (``unanswerable``: counted as lost). A fresh or late command whose interface's
 *       fields fail is refused whatever the enforcement (docs/fci-behaviour.md): a
 *       non-finite generator field, a pose that is no homogeneous transformation (31),
 *       a non-finite elbow sent as valid (``refused_elbow``: 17), a non-finite tau_J_d
 *       under an external controller (``refused_torque`` beside a generator: 34);
 *       ``reason`` names the first field that failed (REASON_* below). The others are
 *       ``accepted`` (``late`` marks the late ones). code bit 1: some command was
 *       unanswerable or refused (the caller logs them); bit 2: some late command of a
 *       joint or Cartesian generator was accepted -- the caller hands those to their
 *       generators' late-datagram rules, clears them from ``accepted`` and calls
 *       ``take``; without bit 2 the take is done;
 *   Arrival.take(commands)
 *       keeps the accepted commands as the cycle's candidates: each interface's field
 *       for every accepted robot while some robot runs it (a generator reads its own
 *       field only), the Cartesian fields of the robots in Cartesian motion, the elbow
 *       while some command or candidate has one; marks them ``have`` and ``started``,
 *       and ``finish`` where the command ends its motion (torque_command_finished under
 *       an external controller alone, motion_generation_finished otherwise);
 *   Arrival.close() -> finishing
 *       the cycle closes: nothing has arrived for the next (``have`` cleared); returns how
 *       many robots' commands end their motion (``finish``, which the caller clears).
 *
 * A wire record is packed: its fields are read with memcpy at any alignment, little-endian
 * as the wire (the build targets little-endian hosts only). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_arrays.h"
#include "_homogeneous.h"

/* Why a command was refused: the first of its interface's fields that failed. */
enum {
    REASON_NONE,
    REASON_Q_C,
    REASON_DQ_C,
    REASON_POSE,         /* O_T_EE_c not finite */
    REASON_TWIST,        /* O_dP_EE_c */
    REASON_ELBOW,        /* elbow_c, sent as valid */
    REASON_TAU,          /* tau_J_d, under an external controller */
    REASON_NOT_HOMOGENEOUS,
};

enum { CODE_LOG = 1, CODE_LATE = 2 };

/* The plan's arrays, in the constructor's order. */
enum { M_ROBOT, M_GENERATOR, M_CONTROLLER, M_BYTES };
enum { I_PUBLISHED, I_FIRST, I_INT64 };
enum {
    F_ANSWERED, F_STARTED, F_HAVE, F_FINISH, F_REFUSED, F_REFUSED_ELBOW, F_REFUSED_TORQUE,
    F_ELBOW_VALID, F_LATE, F_ACCEPTED, F_UNANSWERABLE, F_REASON, F_FLAGS
};
enum { R_Q_C, R_DQ_C, R_TAU_C, R_T_CMD, R_TWIST, R_ELBOW, R_F64 };
/* The record's fields, in the layout's order (after its size). */
enum { L_ID, L_Q_C, L_DQ_C, L_POSE, L_TWIST, L_ELBOW, L_VALID_ELBOW, L_MOTION_FINISHED,
       L_TAU, L_TORQUE_FINISHED, L_FIELDS };
/* The mode values, in the constructor's order. */
enum { K_MOVE, K_JP, K_JV, K_CP, K_CV, K_NONE, K_EXTERNAL, K_MODES };

typedef struct {
    PyObject_HEAD
    Py_ssize_t n;
    Bytes modes[M_BYTES];
    Int64s ids[I_INT64];
    Bytes flags[F_FLAGS];
    F64 rows[R_F64];
    Py_ssize_t size, at[L_FIELDS];
    long mode[K_MODES];
    double tol;
} ArrivalObject;

static void Arrival_dealloc(ArrivalObject *self)
{
    for (int k = 0; k < M_BYTES; k++) bytes_release(&self->modes[k]);
    for (int k = 0; k < I_INT64; k++) int64s_release(&self->ids[k]);
    for (int k = 0; k < F_FLAGS; k++) bytes_release(&self->flags[k]);
    f64_release_all(self->rows, R_F64);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static const char *const MODE_NAMES[M_BYTES] = {"robot_mode", "generator", "controller"};
static const char *const ID_NAMES[I_INT64] = {"published", "first_id"};
static const char *const FLAG_NAMES[F_FLAGS] = {
    "answered", "started",     "have", "finish",   "refused",      "refused_elbow",
    "refused_torque", "elbow_valid", "late", "accepted", "unanswerable", "reason"};
static const char *const ROW_NAMES[R_F64] = {"q_c",   "dq_c",      "tau_c",
                                             "T_cmd", "twist_cmd", "elbow_cmd"};
/* The layout's width of each field in bytes (the record must hold them). */
static const Py_ssize_t FIELD_BYTES[L_FIELDS] = {8, 56, 56, 128, 48, 16, 1, 1, 56, 1};

/* The tuple ``obj`` of ``count`` integers into ``out``. */
static int integers(PyObject *obj, Py_ssize_t count, Py_ssize_t *out, const char *name)
{
    if (!PyTuple_Check(obj) || PyTuple_GET_SIZE(obj) != count) {
        PyErr_Format(PyExc_TypeError, "%s: expected a tuple of %zd integers", name, count);
        return -1;
    }
    for (Py_ssize_t k = 0; k < count; k++) {
        out[k] = PyLong_AsSsize_t(PyTuple_GET_ITEM(obj, k));
        if (out[k] == -1 && PyErr_Occurred()) return -1;
    }
    return 0;
}

static PyObject *Arrival_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "Arrival() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 26, "Arrival") < 0) return NULL;
    PyObject *const *v = &PyTuple_GET_ITEM(args, 0);
    Py_ssize_t n = leading(v[0], "robot_mode");
    if (n < 0) return NULL;
    ArrivalObject *self = (ArrivalObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    int a = 0;
    for (int k = 0; k < M_BYTES; k++)
        if (bytes_get(v[a++], &self->modes[k], n, 0, MODE_NAMES[k]) < 0) goto fail;
    for (int k = 0; k < I_INT64; k++)
        if (int64s_get(v[a++], &self->ids[k], n, 0, ID_NAMES[k]) < 0) goto fail;
    /* The flags in the constructor's order: the accounting's and the cycle input's, the
     * candidates' elbow_valid after the rows, then the outputs. */
    static const int flag_order_1[] = {F_ANSWERED, F_STARTED, F_HAVE, F_FINISH, F_REFUSED,
                                       F_REFUSED_ELBOW, F_REFUSED_TORQUE};
    for (int k = 0; k < 7; k++) {
        int f = flag_order_1[k];
        if (bytes_get(v[a++], &self->flags[f], n, 1, FLAG_NAMES[f]) < 0) goto fail;
    }
    Py_ssize_t s7[2] = {n, 7}, s44[3] = {n, 4, 4}, s6[2] = {n, 6}, s2[2] = {n, 2};
    const Py_ssize_t *shapes[R_F64] = {s7, s7, s7, s44, s6, s2};
    const int ndims[R_F64] = {2, 2, 2, 3, 2, 2};
    for (int k = 0; k < R_F64; k++)
        if (f64_get(v[a++], &self->rows[k], ndims[k], shapes[k], 1, ROW_NAMES[k]) < 0)
            goto fail;
    static const int flag_order_2[] = {F_ELBOW_VALID, F_LATE, F_ACCEPTED, F_UNANSWERABLE,
                                       F_REASON};
    for (int k = 0; k < 5; k++) {
        int f = flag_order_2[k];
        if (bytes_get(v[a++], &self->flags[f], n, 1, FLAG_NAMES[f]) < 0) goto fail;
    }
    Py_ssize_t layout[1 + L_FIELDS];
    if (integers(v[a++], 1 + L_FIELDS, layout, "layout") < 0) goto fail;
    self->size = layout[0];
    for (int k = 0; k < L_FIELDS; k++) {
        Py_ssize_t at = self->at[k] = layout[1 + k];
        if (at < 0 || at + FIELD_BYTES[k] > self->size) {
            PyErr_Format(PyExc_ValueError,
                         "layout: field %d (%zd bytes at %zd) does not fit a %zd-byte command",
                         k, FIELD_BYTES[k], at, self->size);
            goto fail;
        }
    }
    Py_ssize_t modes[K_MODES];
    if (integers(v[a++], K_MODES, modes, "modes") < 0) goto fail;
    for (int k = 0; k < K_MODES; k++) self->mode[k] = (long)modes[k];
    self->tol = PyFloat_AsDouble(v[a]);
    if (self->tol == -1.0 && PyErr_Occurred()) goto fail;
    return (PyObject *)self;
fail:
    Py_DECREF(self);
    return NULL;
}

/* Robot i's modes. */
typedef struct {
    int motion, jp, jv, cp, cv, cartesian, external, torque_only;
} RobotModes;

static inline RobotModes modes_of(const ArrivalObject *self, Py_ssize_t i)
{
    RobotModes r;
    memset(&r, 0, sizeof(r));
    r.motion = BYTE1(self->modes[M_ROBOT], i) == self->mode[K_MOVE];
    if (!r.motion) return r;
    long gen = BYTE1(self->modes[M_GENERATOR], i);
    r.jp = gen == self->mode[K_JP];
    r.jv = gen == self->mode[K_JV];
    r.cp = gen == self->mode[K_CP];
    r.cv = gen == self->mode[K_CV];
    r.cartesian = r.cp || r.cv;
    r.torque_only = gen == self->mode[K_NONE];
    r.external = BYTE1(self->modes[M_CONTROLLER], i) == self->mode[K_EXTERNAL];
    return r;
}

/* ``count`` doubles of a record's field, read at any alignment. */
static inline void field(const char *record, Py_ssize_t at, int count, double *out)
{
    memcpy(out, record + at, sizeof(double) * (size_t)count);
}

static inline int all_finite(const double *x, int count)
{
    for (int k = 0; k < count; k++)
        if (!isfinite(x[k])) return 0;
    return 1;
}

/* Whether one command passes its robot's interface: REASON_NONE, or the first field that
 * failed -- the generator's, then the elbow (Cartesian generators), then the torque
 * (an external controller), as the robot names them (engine.py judge_non_finite). */
static int refusal(const ArrivalObject *self, const char *record, RobotModes r)
{
    double x[16];
    if (r.jp) {
        field(record, self->at[L_Q_C], 7, x);
        if (!all_finite(x, 7)) return REASON_Q_C;
    }
    if (r.jv) {
        field(record, self->at[L_DQ_C], 7, x);
        if (!all_finite(x, 7)) return REASON_DQ_C;
    }
    if (r.cp) {
        double wire[16];
        field(record, self->at[L_POSE], 16, wire);
        if (!all_finite(wire, 16)) return REASON_POSE;
        for (int row = 0; row < 4; row++) /* the wire's column-major to row-major */
            for (int col = 0; col < 4; col++) x[4 * row + col] = wire[4 * col + row];
        if (!homogeneous_passes(x, self->tol)) return REASON_NOT_HOMOGENEOUS;
    }
    if (r.cv) {
        field(record, self->at[L_TWIST], 6, x);
        if (!all_finite(x, 6)) return REASON_TWIST;
    }
    if (r.cartesian && record[self->at[L_VALID_ELBOW]]) {
        field(record, self->at[L_ELBOW], 2, x);
        if (!all_finite(x, 2)) return REASON_ELBOW;
    }
    if (r.external) {
        field(record, self->at[L_TAU], 7, x);
        if (!all_finite(x, 7)) return REASON_TAU;
    }
    return REASON_NONE;
}

/* The (n,) RobotCommand records of ``obj``, C-contiguous. */
static int records_get(const ArrivalObject *self, PyObject *obj, Py_buffer *view)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS) < 0) {
        PyErr_Clear();
        PyErr_SetString(PyExc_ValueError, "commands: expected a C-contiguous RobotCommand array");
        return -1;
    }
    if (view->len != self->n * self->size) {
        PyErr_Format(PyExc_ValueError, "commands: %zd bytes, expected %zd commands of %zd",
                     view->len, self->n, self->size);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static void take_records(ArrivalObject *self, const char *base)
{
    Py_ssize_t n = self->n;
    Bytes *f = self->flags;
    /* Which interfaces some robot runs, and whether an elbow is about. */
    int jp = 0, jv = 0, external = 0, cp = 0, cv = 0, elbow = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        RobotModes r = modes_of(self, i);
        jp |= r.jp, jv |= r.jv, external |= r.external, cp |= r.cp, cv |= r.cv;
        elbow |= base[i * self->size + self->at[L_VALID_ELBOW]] != 0;
        elbow |= BYTE1(f[F_ELBOW_VALID], i) != 0;
    }
    F64 *rows = self->rows;
    double x[16];
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!BYTE1(f[F_ACCEPTED], i)) continue;
        const char *record = base + i * self->size;
        RobotModes r = modes_of(self, i);
        if (jp) {
            field(record, self->at[L_Q_C], 7, x);
            for (int j = 0; j < 7; j++) AT2(rows[R_Q_C], i, j) = x[j];
        }
        if (jv) {
            field(record, self->at[L_DQ_C], 7, x);
            for (int j = 0; j < 7; j++) AT2(rows[R_DQ_C], i, j) = x[j];
        }
        if (external) {
            field(record, self->at[L_TAU], 7, x);
            for (int j = 0; j < 7; j++) AT2(rows[R_TAU_C], i, j) = x[j];
        }
        if (r.cartesian) {
            if (cp) { /* the wire's column-major pose, T_cmd row-major */
                field(record, self->at[L_POSE], 16, x);
                for (int row = 0; row < 4; row++)
                    for (int col = 0; col < 4; col++)
                        AT3(rows[R_T_CMD], i, row, col) = x[4 * col + row];
            }
            if (cv) {
                field(record, self->at[L_TWIST], 6, x);
                for (int j = 0; j < 6; j++) AT2(rows[R_TWIST], i, j) = x[j];
            }
            if (elbow) {
                field(record, self->at[L_ELBOW], 2, x);
                for (int j = 0; j < 2; j++) AT2(rows[R_ELBOW], i, j) = x[j];
                BYTE1(f[F_ELBOW_VALID], i) = record[self->at[L_VALID_ELBOW]] != 0;
            }
        }
        BYTE1(f[F_HAVE], i) = 1;
        BYTE1(f[F_STARTED], i) = 1;
        int finished = r.torque_only ? record[self->at[L_TORQUE_FINISHED]]
                                     : record[self->at[L_MOTION_FINISHED]];
        if (finished) BYTE1(f[F_FINISH], i) = 1;
    }
}

static PyObject *Arrival_arrive(ArrivalObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "arrive") < 0) return NULL;
    Py_ssize_t n = self->n;
    Py_buffer view;
    Bytes mask;
    if (records_get(self, args[0], &view) < 0) return NULL;
    if (bytes_get(args[1], &mask, n, 0, "mask") < 0) {
        PyBuffer_Release(&view);
        return NULL;
    }
    const char *base = view.buf;
    Bytes *f = self->flags;
    int code = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        BYTE1(f[F_LATE], i) = BYTE1(f[F_ACCEPTED], i) = BYTE1(f[F_UNANSWERABLE], i) = 0;
        BYTE1(f[F_REASON], i) = REASON_NONE;
        if (!BYTE1(mask, i)) continue;
        RobotModes r = modes_of(self, i);
        if (!r.motion) continue; /* ignored, as the robot ignores them */
        const char *record = base + i * self->size;
        uint64_t id;
        memcpy(&id, record + self->at[L_ID], 8);
        uint64_t published = (uint64_t)INT64_AT(self->ids[I_PUBLISHED], i);
        uint64_t first = (uint64_t)INT64_AT(self->ids[I_FIRST], i);
        int fresh = id == published;
        int late = !fresh && id < published && id >= first;
        if (fresh) BYTE1(f[F_ANSWERED], i) = 1;
        if (!fresh && !late) {
            BYTE1(f[F_UNANSWERABLE], i) = 1;
            code |= CODE_LOG;
            continue;
        }
        int reason = refusal(self, record, r);
        if (reason != REASON_NONE) {
            BYTE1(f[F_REASON], i) = (unsigned char)reason;
            BYTE1(f[F_REFUSED], i) = 1;
            if (reason == REASON_ELBOW) BYTE1(f[F_REFUSED_ELBOW], i) = 1;
            if (reason == REASON_TAU && !r.torque_only) BYTE1(f[F_REFUSED_TORQUE], i) = 1;
            code |= CODE_LOG;
            continue;
        }
        BYTE1(f[F_ACCEPTED], i) = 1;
        if (late) {
            BYTE1(f[F_LATE], i) = 1;
            if (r.jp || r.jv || r.cartesian) code |= CODE_LATE;
        }
    }
    if (!(code & CODE_LATE)) take_records(self, base);
    bytes_release(&mask);
    PyBuffer_Release(&view);
    return PyLong_FromLong(code);
}

static PyObject *Arrival_take(ArrivalObject *self, PyObject *commands)
{
    Py_buffer view;
    if (records_get(self, commands, &view) < 0) return NULL;
    take_records(self, view.buf);
    PyBuffer_Release(&view);
    Py_RETURN_NONE;
}

static PyObject *Arrival_close(ArrivalObject *self, PyObject *unused)
{
    (void)unused;
    Py_ssize_t finishing = 0;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        BYTE1(self->flags[F_HAVE], i) = 0;
        finishing += BYTE1(self->flags[F_FINISH], i) != 0;
    }
    return PyLong_FromSsize_t(finishing);
}

static PyMethodDef Arrival_methods[] = {
    {"arrive", (PyCFunction)(void (*)(void))Arrival_arrive, METH_FASTCALL,
     "arrive(commands, mask) -> code: classify the delivered commands, refuse those that "
     "fail, take the others (unless code bit 2: late ones for the generators first)."},
    {"take", (PyCFunction)Arrival_take, METH_O,
     "take(commands): keep the accepted commands as the cycle's candidates."},
    {"close", (PyCFunction)Arrival_close, METH_NOARGS,
     "close() -> finishing: clear have for the next cycle; how many commands finished."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject ArrivalType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.fci._arrival.Arrival",
    .tp_basicsize = sizeof(ArrivalObject),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A plan over the controller's arrays: the arrival of RobotCommands.",
    .tp_new = Arrival_new,
    .tp_dealloc = (destructor)Arrival_dealloc,
    .tp_methods = Arrival_methods,
};

static struct PyModuleDef _arrival_definition = {
    PyModuleDef_HEAD_INIT, "_arrival",
    "The arrival of RobotCommands: fresh, late or answering nothing; refused or taken "
    "(fci/arrival.py).",
    -1, NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__arrival(void)
{
    if (PyType_Ready(&ArrivalType) < 0) return NULL;
    PyObject *module = kernel_module(&_arrival_definition);
    if (!module) return NULL;
    if (PyModule_AddObjectRef(module, "Arrival", (PyObject *)&ArrivalType) < 0) {
        Py_DECREF(module);
        return NULL;
    }
    return module;
}
