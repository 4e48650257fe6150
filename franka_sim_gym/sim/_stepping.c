/* Every arm's world through one cycle's physics, sim/arm.py ArmPhysics.step: its one
 * text (issue 38), required (native.require):
 *
 *   Steps(functions, models, datas, forcerange, act, applied)
 *       a plan: MuJoCo's mj_step2 and mj_step1 (the addresses of the functions the
 *       Python bindings' own libmujoco exports, sim/libmujoco.py), each arm's MjModel
 *       and MjData, and for one shared model with a hand its actuator force range
 *       ((nu, 2) float64, the model's own array), the fingers' actuator row and the
 *       (1,) limit the model holds now (shared with ArmPhysics, which sets it too);
 *   Steps.run(finger_force)
 *       arm by arm: the shared model's finger limit set to the arm's (finger_force (n,)
 *       float64, or None) where it differs from the one it holds, then mj_step2 and
 *       mj_step1 of the arm's world -- what n calls of each binding did, without their
 *       per-call cost (about 0.4 us each: 50 us of a 64-arm cycle);
 *   Steps.servo_run(finger_force, q_ref, dq_ref, kp, kd, compensation)
 *       first the internal joint impedance servo, sim/arm.py ArmPhysics.step's law:
 *       tau = (q_ref - q) kp + (dq_ref - dq) kd + coriolis (dq_ref None: - kd dq, a
 *       reference at rest) + compensation (None: none), each arm's into its MjData's
 *       ctrl rows, then run's steps. (n, 7) each; q, dq (what the servo reads: the true
 *       joints, or a reality draw's measurement of them), coriolis and the ctrl rows
 *       (a tuple of n writable 7-float buffers) are the plan's, given by
 *       Steps.servo(q, dq, coriolis, ctrl) once;
 *   Steps.limit(i, finger_force)
 *       the shared model's finger limit set to arm i's alone (before a forward of its
 *       world);
 *   Steps.torque(q_ref, dq_ref, kp, kd, compensation)
 *       the servo's torque alone (the arms under another servo then write their own);
 *   Steps.own(servo_tau, servo_arms, external_tau, external_arms, compensation)
 *       the arms with a torque of their own, into their ctrl rows: under an external
 *       controller (external_arms) the client's torque, gravity being the actuators'
 *       (tau = external_tau + compensation); under the Cartesian impedance servo
 *       (servo_arms, sim/cartesian_servo.py) its torque and the same Coriolis the joint
 *       servo adds (tau = servo_tau + coriolis + compensation); an arm in both is
 *       external's. (n, 7) torques and (n,) bool masks, each pair None for none, and
 *       compensation None for none; the other arms' rows are left as they are.
 *
 * The same library and the same calls in the same order: the same bits as the bindings'.
 * A MuJoCo error inside a step (mju_error: the bindings raise mujoco.FatalError) is caught
 * by a log handler installed with MuJoCo's mju_setLogHandler for the loop only (MuJoCo's
 * documented way to recover from an error: the handler longjmps back), and raised as a
 * RuntimeError naming the arm; that arm's MjData is then as MuJoCo left it. Every other
 * message (warnings, another thread's) goes on to the handler the loop replaced. The
 * recovery point is the calling thread's own; a step inside a step (a Python callback of
 * MuJoCo stepping again) is refused. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <setjmp.h>
#include <stdio.h>
#include <string.h>

#include "_arrays.h"

typedef void (*StepFn)(const void *model, void *data);

/* MuJoCo 4's mjLogMessage, its leading fields as mjtype.h declares them (the handler only
 * reads these), and mju_setLogHandler's types. */
typedef struct {
    int level; /* mjtLogLevel */
    int topic;
    char subject[1024];
    const char *body;
} LogMessage;
typedef void (*LogHandler)(const LogMessage *message);
typedef LogHandler (*SetLogHandler)(LogHandler handler);
enum { LOG_ERROR = 3 }; /* mjLOG_ERROR */

typedef struct {
    PyObject_HEAD
    StepFn step2, step1;
    SetLogHandler set_log_handler; /* MuJoCo's mju_setLogHandler */
    Py_ssize_t n;
    const void **models;
    void **datas;
    PyObject *keep; /* the models, datas and arrays, alive as long as the plan */
    F64 forcerange, applied;
    Py_ssize_t act; /* -1: no shared finger limit to set */
    int servo;      /* servo_run's arrays are given */
    F64 q, dq, coriolis;
    Py_buffer *ctrl; /* n of them */
    Py_ssize_t nctrl;
} StepsObject;

/* The calling thread's recovery point while its loop runs (armed), the error a step
 * raised, and the handler the loop replaced (set and restored with the GIL held). */
static __thread jmp_buf error_jump;
static __thread int armed;
static __thread char error_text[1536];
static LogHandler replaced;

static void on_log(const LogMessage *message)
{
    if (armed && message->level == LOG_ERROR) {
        armed = 0;
        snprintf(error_text, sizeof(error_text), "%s%s%s", message->subject,
                 message->body ? "\n" : "", message->body ? message->body : "");
        longjmp(error_jump, 1);
    }
    if (replaced) replaced(message);
}

static void servo_release(StepsObject *self)
{
    f64_release(&self->q);
    f64_release(&self->dq);
    f64_release(&self->coriolis);
    for (Py_ssize_t k = 0; k < self->nctrl; k++) PyBuffer_Release(&self->ctrl[k]);
    PyMem_Free(self->ctrl);
    self->ctrl = NULL;
    self->nctrl = 0;
    self->servo = 0;
}

static void Steps_dealloc(StepsObject *self)
{
    servo_release(self);
    f64_release(&self->forcerange);
    f64_release(&self->applied);
    PyMem_Free(self->models);
    PyMem_Free(self->datas);
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static void *address_of(PyObject *obj, const char *name, Py_ssize_t i)
{
    void *p = PyLong_Check(obj) ? PyLong_AsVoidPtr(obj) : NULL;
    if (!p && !PyErr_Occurred())
        PyErr_Format(PyExc_ValueError, "%s[%zd]: expected a non-null address", name, i);
    return p;
}

/* The struct address behind a MuJoCo binding object of type ``kind`` (its ``_address``). */
static void *struct_address(PyObject *obj, const char *kind, const char *name, Py_ssize_t i)
{
    const char *type = Py_TYPE(obj)->tp_name, *dot = strrchr(type, '.');
    PyObject *address = NULL;
    if (strcmp(dot ? dot + 1 : type, kind) != 0 ||
        !(address = PyObject_GetAttrString(obj, "_address"))) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s[%zd]: expected a mujoco.%s, got %s", name, i, kind,
                     type);
        return NULL;
    }
    void *p = address_of(address, name, i);
    Py_DECREF(address);
    return p;
}

static PyObject *Steps_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    if (kwargs && PyDict_Size(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "Steps() takes no keyword arguments");
        return NULL;
    }
    if (check_nargs(PyTuple_GET_SIZE(args), 6, "Steps") < 0) return NULL;
    PyObject *functions = PyTuple_GET_ITEM(args, 0), *models = PyTuple_GET_ITEM(args, 1),
             *datas = PyTuple_GET_ITEM(args, 2), *forcerange = PyTuple_GET_ITEM(args, 3),
             *act = PyTuple_GET_ITEM(args, 4), *applied = PyTuple_GET_ITEM(args, 5);
    if (!PyTuple_Check(functions) || PyTuple_GET_SIZE(functions) != 3) {
        PyErr_SetString(PyExc_TypeError,
                        "functions: expected a tuple (mj_step2, mj_step1, mju_setLogHandler) "
                        "of addresses");
        return NULL;
    }
    if (!PyTuple_Check(models) || !PyTuple_Check(datas)) {
        PyErr_SetString(PyExc_TypeError, "models and datas must be tuples");
        return NULL;
    }
    Py_ssize_t n = PyTuple_GET_SIZE(datas);
    if (PyTuple_GET_SIZE(models) != n) {
        PyErr_Format(PyExc_ValueError, "models: %zd of them for %zd datas",
                     PyTuple_GET_SIZE(models), n);
        return NULL;
    }
    StepsObject *self = (StepsObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->n = n;
    self->act = -1;
    self->keep = PyTuple_Pack(5, models, datas, forcerange, act, applied);
    self->models = PyMem_Calloc((size_t)n + 1, sizeof(void *));
    self->datas = PyMem_Calloc((size_t)n + 1, sizeof(void *));
    if (!self->keep || !self->models || !self->datas) {
        Py_DECREF(self);
        return PyErr_NoMemory();
    }
    void *f[3];
    for (Py_ssize_t k = 0; k < 3; k++) {
        if (!(f[k] = address_of(PyTuple_GET_ITEM(functions, k), "functions", k))) {
            Py_DECREF(self);
            return NULL;
        }
    }
    self->step2 = (StepFn)f[0];
    self->step1 = (StepFn)f[1];
    self->set_log_handler = (SetLogHandler)f[2];
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!(self->models[i] = struct_address(PyTuple_GET_ITEM(models, i), "MjModel", "models", i)) ||
            !(self->datas[i] = struct_address(PyTuple_GET_ITEM(datas, i), "MjData", "datas", i))) {
            Py_DECREF(self);
            return NULL;
        }
    }
    if (forcerange != Py_None) {
        Py_ssize_t any2[2] = {-1, 2}, one[1] = {1};
        if (f64_get(forcerange, &self->forcerange, 2, any2, 1, "forcerange") < 0 ||
            f64_get(applied, &self->applied, 1, one, 1, "applied") < 0) {
            Py_DECREF(self);
            return NULL;
        }
        Py_ssize_t row = PyLong_AsSsize_t(act);
        if (row == -1 && PyErr_Occurred()) {
            Py_DECREF(self);
            return NULL;
        }
        if (row < 0 || row >= self->forcerange.shape[0]) {
            PyErr_Format(PyExc_ValueError, "act: %zd is not a row of forcerange (%zd rows)",
                         row, self->forcerange.shape[0]);
            Py_DECREF(self);
            return NULL;
        }
        self->act = row;
    }
    return (PyObject *)self;
}

static PyObject *steps(StepsObject *self, PyObject *finger_force);

/* The shared model's finger limit set to arm i's (force (n,)), where it differs from the
 * one it holds (as numpy's !=: a NaN limit is set every time). */
static inline void apply_limit(StepsObject *self, const F64 *force, Py_ssize_t i)
{
    double want = AT1(*force, i), *held = &AT1(self->applied, 0);
    if (want != *held) {
        AT2(self->forcerange, self->act, 0) = -want;
        AT2(self->forcerange, self->act, 1) = want;
        *held = want;
    }
}

/* Steps.limit(i, finger_force): arm i's finger limit on the shared model before anything
 * else computes arm i's world (a forward after a reset); nothing without a shared one. */
static PyObject *Steps_limit(StepsObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 2, "limit") < 0) return NULL;
    Py_ssize_t i = PyLong_AsSsize_t(args[0]);
    if (i == -1 && PyErr_Occurred()) return NULL;
    if (i < 0 || i >= self->n) {
        PyErr_Format(PyExc_ValueError, "limit: arm %zd is not one of the %zd arms", i, self->n);
        return NULL;
    }
    if (self->act < 0 || args[1] == Py_None) Py_RETURN_NONE;
    F64 force;
    Py_ssize_t sn[1] = {self->n};
    if (f64_get(args[1], &force, 1, sn, 0, "finger_force") < 0) return NULL;
    apply_limit(self, &force, i);
    f64_release(&force);
    Py_RETURN_NONE;
}

static PyObject *Steps_run(StepsObject *self, PyObject *finger_force)
{
    return steps(self, finger_force);
}

/* Steps.servo(q, dq, coriolis, ctrl): servo_run's arrays, held (replacing any before). */
static PyObject *Steps_servo(StepsObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 4, "servo") < 0) return NULL;
    servo_release(self);
    Py_ssize_t s7[2] = {self->n, 7};
    PyObject *ctrl = args[3];
    if (f64_get(args[0], &self->q, 2, s7, 0, "q") < 0 ||
        f64_get(args[1], &self->dq, 2, s7, 0, "dq") < 0 ||
        f64_get(args[2], &self->coriolis, 2, s7, 0, "coriolis") < 0)
        goto fail;
    if (!PyTuple_Check(ctrl) || PyTuple_GET_SIZE(ctrl) != self->n) {
        PyErr_Format(PyExc_TypeError, "ctrl: expected a tuple of %zd buffers", self->n);
        goto fail;
    }
    if (!(self->ctrl = PyMem_Calloc((size_t)self->n + 1, sizeof(Py_buffer)))) {
        PyErr_NoMemory();
        goto fail;
    }
    for (Py_ssize_t i = 0; i < self->n; i++) {
        Py_buffer *view = &self->ctrl[i];
        int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE;
        if (PyObject_GetBuffer(PyTuple_GET_ITEM(ctrl, i), view, flags) < 0) {
            PyErr_Clear();
            PyErr_Format(PyExc_ValueError,
                         "ctrl[%zd]: expected a C-contiguous writable float64 array", i);
            goto fail;
        }
        self->nctrl++;
        const char *f = view->format;
        if (f && (*f == '<' || *f == '=' || *f == '@')) f++;
        if (!f || strcmp(f, "d") != 0 || view->len != 7 * 8) {
            PyErr_Format(PyExc_ValueError, "ctrl[%zd]: expected 7 float64 values", i);
            goto fail;
        }
    }
    self->servo = 1;
    Py_RETURN_NONE;
fail:
    servo_release(self);
    return NULL;
}

/* What the drives add to a servo's torque tau of arm i, joint j: the Coriolis (joint and
 * Cartesian servo alike) and a configured load's compensation (``comp`` NULL: none), in
 * the order numpy's in-place lines summed them (the same bits). */
static inline double with_drive_terms(double tau, const F64 *coriolis, const F64 *comp,
                                      Py_ssize_t i, int j)
{
    tau += AT2(*coriolis, i, j);
    return comp ? tau + AT2(*comp, i, j) : tau;
}

/* The joint servo's torque into every arm's ctrl rows, from args (q_ref, dq_ref, kp, kd,
 * compensation); 0, or -1 with an exception naming ``name``. */
static int servo_torque(StepsObject *self, PyObject *const *args, const char *name)
{
    if (!self->servo) {
        PyErr_Format(PyExc_RuntimeError, "%s: no servo arrays (Steps.servo first)", name);
        return -1;
    }
    enum { Q_REF, DQ_REF, KP, KD, COMPENSATION, COUNT };
    F64 a[COUNT];
    memset(a, 0, sizeof(a));
    Py_ssize_t s7[2] = {self->n, 7};
    int at_rest = args[1] == Py_None, compensated = args[4] != Py_None, status = -1;
    if (f64_get(args[0], &a[Q_REF], 2, s7, 0, "q_ref") < 0 ||
        (!at_rest && f64_get(args[1], &a[DQ_REF], 2, s7, 0, "dq_ref") < 0) ||
        f64_get(args[2], &a[KP], 2, s7, 0, "kp") < 0 ||
        f64_get(args[3], &a[KD], 2, s7, 0, "kd") < 0 ||
        (compensated && f64_get(args[4], &a[COMPENSATION], 2, s7, 0, "compensation") < 0))
        goto done;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        double *ctrl = (double *)self->ctrl[i].buf;
        for (int j = 0; j < 7; j++) {
            /* the order numpy's in-place lines summed in: the same bits */
            double tau = (AT2(a[Q_REF], i, j) - AT2(self->q, i, j)) * AT2(a[KP], i, j);
            if (at_rest)
                tau -= AT2(a[KD], i, j) * AT2(self->dq, i, j);
            else
                tau += (AT2(a[DQ_REF], i, j) - AT2(self->dq, i, j)) * AT2(a[KD], i, j);
            ctrl[j] = with_drive_terms(tau, &self->coriolis,
                                       compensated ? &a[COMPENSATION] : NULL, i, j);
        }
    }
    status = 0;
done:
    f64_release_all(a, COUNT);
    return status;
}

static PyObject *Steps_torque(StepsObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 5, "torque") < 0 || servo_torque(self, args, "torque") < 0)
        return NULL;
    Py_RETURN_NONE;
}

static PyObject *Steps_own(StepsObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 5, "own") < 0) return NULL;
    if (!self->servo) {
        PyErr_SetString(PyExc_RuntimeError, "own: no servo arrays (Steps.servo first)");
        return NULL;
    }
    enum { SERVO, EXTERNAL, COMPENSATION, COUNT };
    F64 a[COUNT];
    Bytes servo_arms, external_arms;
    memset(a, 0, sizeof(a));
    memset(&servo_arms, 0, sizeof(servo_arms));
    memset(&external_arms, 0, sizeof(external_arms));
    Py_ssize_t s7[2] = {self->n, 7};
    int servo = args[0] != Py_None, external = args[2] != Py_None;
    int compensated = args[4] != Py_None;
    PyObject *result = NULL;
    if ((servo != (args[1] != Py_None)) || (external != (args[3] != Py_None))) {
        PyErr_SetString(PyExc_ValueError,
                        "own: a torque and its arms come together (both None for none)");
        goto done;
    }
    if ((servo && (f64_get(args[0], &a[SERVO], 2, s7, 0, "servo_tau") < 0 ||
                   bytes_get(args[1], &servo_arms, self->n, 0, "servo_arms") < 0)) ||
        (external && (f64_get(args[2], &a[EXTERNAL], 2, s7, 0, "external_tau") < 0 ||
                      bytes_get(args[3], &external_arms, self->n, 0, "external_arms") < 0)) ||
        (compensated && f64_get(args[4], &a[COMPENSATION], 2, s7, 0, "compensation") < 0))
        goto done;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        int under = external && BYTE1(external_arms, i);
        if (!under && !(servo && BYTE1(servo_arms, i))) continue;
        double *ctrl = (double *)self->ctrl[i].buf;
        for (int j = 0; j < 7; j++) {
            const F64 *comp = compensated ? &a[COMPENSATION] : NULL;
            /* the client's torque has no Coriolis added (libfranka's torque control) */
            ctrl[j] = under ? (comp ? AT2(a[EXTERNAL], i, j) + AT2(*comp, i, j)
                                    : AT2(a[EXTERNAL], i, j))
                            : with_drive_terms(AT2(a[SERVO], i, j), &self->coriolis, comp, i, j);
        }
    }
    result = Py_None;
    Py_INCREF(result);
done:
    f64_release_all(a, COUNT);
    bytes_release(&servo_arms);
    bytes_release(&external_arms);
    return result;
}

static PyObject *Steps_servo_run(StepsObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (check_nargs(nargs, 6, "servo_run") < 0 || servo_torque(self, args + 1, "servo_run") < 0)
        return NULL;
    return steps(self, args[0]);
}

static PyObject *steps(StepsObject *self, PyObject *finger_force)
{
    F64 force;
    memset(&force, 0, sizeof(force));
    int limits = self->act >= 0 && finger_force != Py_None;
    if (limits) {
        Py_ssize_t sn[1] = {self->n};
        if (f64_get(finger_force, &force, 1, sn, 0, "finger_force") < 0) return NULL;
    }
    if (armed) {
        f64_release(&force);
        PyErr_SetString(PyExc_RuntimeError, "Steps: a step inside a step (from a callback)");
        return NULL;
    }
    /* volatile: read after the jump */
    volatile Py_ssize_t i = 0;
    if (setjmp(error_jump)) {
        self->set_log_handler(replaced);
        replaced = NULL;
        f64_release(&force);
        PyErr_Format(PyExc_RuntimeError, "MuJoCo error in arm %zd's step: %s", (Py_ssize_t)i,
                     error_text);
        return NULL;
    }
    replaced = self->set_log_handler(on_log);
    armed = 1;
    for (; i < self->n; i++) {
        if (limits) apply_limit(self, &force, i);
        self->step2(self->models[i], self->datas[i]);
        self->step1(self->models[i], self->datas[i]);
    }
    armed = 0;
    self->set_log_handler(replaced);
    replaced = NULL;
    f64_release(&force);
    Py_RETURN_NONE;
}

static PyMethodDef STEPS_METHODS[] = {
    {"run", (PyCFunction)Steps_run, METH_O,
     "run(finger_force): every arm's mj_step2 then mj_step1, the shared finger limit set "
     "to the arm's first (finger_force (n,) float64, or None)."},
    {"limit", (PyCFunction)(void (*)(void))Steps_limit, METH_FASTCALL,
     "limit(i, finger_force): the shared model's finger limit set to arm i's."},
    {"servo", (PyCFunction)(void (*)(void))Steps_servo, METH_FASTCALL,
     "servo(q, dq, coriolis, ctrl): the arrays servo_run's joint servo reads and writes."},
    {"torque", (PyCFunction)(void (*)(void))Steps_torque, METH_FASTCALL,
     "torque(q_ref, dq_ref, kp, kd, compensation): the joint servo's torque into every "
     "arm's ctrl rows (no step)."},
    {"own", (PyCFunction)(void (*)(void))Steps_own, METH_FASTCALL,
     "own(servo_tau, servo_arms, external_tau, external_arms, compensation): the arms "
     "with a torque of their own into their ctrl rows (see the module's text)."},
    {"servo_run", (PyCFunction)(void (*)(void))Steps_servo_run, METH_FASTCALL,
     "servo_run(finger_force, q_ref, dq_ref, kp, kd, compensation): the joint servo's "
     "torque into every arm's ctrl rows, then run(finger_force)."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject StepsType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "franka_sim_gym.sim._stepping.Steps",
    .tp_basicsize = sizeof(StepsObject),
    .tp_dealloc = (destructor)Steps_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Steps(functions, models, datas, forcerange, act, applied): a cycle's "
              "physics of every arm, by run(finger_force).",
    .tp_methods = STEPS_METHODS,
    .tp_new = Steps_new,
};

static struct PyModuleDef _stepping_definition = {
    PyModuleDef_HEAD_INIT, "_stepping", "Every arm's world through one cycle's physics.", -1,
    NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__stepping(void)
{
    if (PyType_Ready(&StepsType) < 0) return NULL;
    PyObject *m = kernel_module(&_stepping_definition);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "Steps", (PyObject *)&StepsType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
