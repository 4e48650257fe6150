/* The cycle accounting's close of a cycle (docs/fci-behaviour.md "The cycle contract" and
 * "What the sim does with a lost cycle"), its only text; fci/accounting.py
 * CycleAccounting.close_cycle calls it once a cycle for every robot:
 *
 *   close_cycle(answered, started, ring, pos, answered_sum, counted, lost_total, lost_run,
 *               longest_lost_run, rate, window, bound) -> at_bound
 *
 * For a robot whose accounting is open (``started``): the cycle enters its window (ring
 * column ``pos``, the oldest entry leaving) as answered or not, a cycle not answered is
 * lost (the run goes on, the longest run and the count follow), an answered one ends the
 * run; control_command_success_rate is the answered cycles over the cycles the window
 * holds (what it holds while it fills). A robot whose accounting is not open keeps its
 * cleared window, rate 0.0, and its run as it is (AutomaticErrorRecovery re-arms it).
 * ``answered`` is cleared for the next cycle. Returns how many robots' runs are at ``bound``
 * or past it (the 20-cycle bound, docs/fci-behaviour.md: the caller's "none", its usual
 * answer, without a reduce).
 *
 *   lost_runs(sending, answered, robot_answers, lost, lost_run, longest_lost_run) -> bool
 *
 * The same run law for the env's links (envs/channel.py Links, what ``info`` reports): a
 * sending arm whose cycle neither a datagram nor the robot itself (the asynchronous
 * generator) answered lost it (its count and run go on), one answered ends its run; an
 * arm not sending keeps its run. True when some run is open. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "_arrays.h"

/* A cycle of an open accounting: answered ends the run, else the cycle is lost (the run
 * goes on, the count and the longest run follow). */
static inline void run_law(int answered, long long *run, long long *lost, long long *longest)
{
    if (answered) {
        *run = 0;
        return;
    }
    *lost += 1;
    if (++*run > *longest) *longest = *run;
}

static PyObject *close_cycle(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    enum { SUM, COUNTED, LOST_TOTAL, LOST_RUN, LONGEST, COUNTERS };
    static const char *names[COUNTERS] = {"answered_sum", "counted", "lost_total", "lost_run",
                                          "longest_lost_run"};
    Bytes answered, started;
    Int64s counters[COUNTERS];
    F64 rate;
    Py_buffer ring = {0};
    memset(&answered, 0, sizeof(answered));
    memset(&started, 0, sizeof(started));
    memset(counters, 0, sizeof(counters));
    memset(&rate, 0, sizeof(rate));
    PyObject *result = NULL;
    if (check_nargs(nargs, 12, "close_cycle") < 0) return NULL;
    Py_ssize_t n = leading(args[1], "started");
    if (n < 0) return NULL;
    Py_ssize_t pos = PyLong_AsSsize_t(args[3]), window = PyLong_AsSsize_t(args[10]);
    long long bound = PyLong_AsLongLong(args[11]);
    if ((pos == -1 || window == -1 || bound == -1) && PyErr_Occurred()) return NULL;
    if (window < 1 || pos < 0 || pos >= window) {
        PyErr_Format(PyExc_ValueError, "close_cycle: pos %zd outside a window of %zd", pos,
                     window);
        return NULL;
    }
    Py_ssize_t s1[1] = {n};
    /* ``answered`` is written (cleared): numpy's bool, one byte, read and written as such */
    if (PyObject_GetBuffer(args[0], &answered.view, PyBUF_RECORDS) < 0 ||
        answered.view.ndim != 1 || answered.view.shape[0] != n || answered.view.itemsize != 1) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "answered: expected a writable bool array of shape (%zd,)", n);
        goto done;
    }
    answered.data = answered.view.buf;
    answered.stride = answered.view.strides ? answered.view.strides[0] : 1;
    if (bytes_get(args[1], &started, n, 0, "started") < 0) goto done;
    if (PyObject_GetBuffer(args[2], &ring, PyBUF_RECORDS) < 0 || ring.ndim != 2 ||
        ring.shape[0] != n || ring.shape[1] != window || ring.itemsize != 1) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "ring: expected a writable bool array of shape (%zd, %zd)",
                     n, window);
        goto done;
    }
    for (int k = 0; k < COUNTERS; k++)
        if (int64s_get(args[4 + k], &counters[k], n, 1, names[k]) < 0) goto done;
    if (f64_get(args[9], &rate, 1, s1, 1, "rate") < 0) goto done;
    Py_ssize_t at_bound = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        const int is_answered = BYTE1(answered, i) != 0;
        BYTE1(answered, i) = 0;
        if (!BYTE1(started, i)) { /* a cleared window, rate 0.0; the run as it is */
            at_bound += INT64_AT(counters[LOST_RUN], i) >= bound;
            continue;
        }
        unsigned char *slot = (unsigned char *)ring.buf + i * ring.strides[0] + pos * ring.strides[1];
        const long long sum = INT64_AT(counters[SUM], i) + is_answered - (*slot != 0);
        *slot = (unsigned char)is_answered;
        INT64_AT(counters[SUM], i) = sum;
        const long long counted = ++INT64_AT(counters[COUNTED], i);
        run_law(is_answered, &INT64_AT(counters[LOST_RUN], i),
                &INT64_AT(counters[LOST_TOTAL], i), &INT64_AT(counters[LONGEST], i));
        /* while the window fills the divisor is what it holds (never 0 here) */
        const long long held = counted < window ? counted : window;
        AT1(rate, i) = (double)sum / (double)held;
        at_bound += INT64_AT(counters[LOST_RUN], i) >= bound;
    }
    result = PyLong_FromSsize_t(at_bound);
done:
    if (answered.view.obj) PyBuffer_Release(&answered.view);
    bytes_release(&started);
    if (ring.obj) PyBuffer_Release(&ring);
    for (int k = 0; k < COUNTERS; k++) int64s_release(&counters[k]);
    f64_release(&rate);
    return result;
}

static PyObject *lost_runs(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    static const char *names[3] = {"lost", "lost_run", "longest_lost_run"};
    Bytes sending, answered, itself;
    Int64s counters[3];
    memset(&sending, 0, sizeof(sending));
    memset(&answered, 0, sizeof(answered));
    memset(&itself, 0, sizeof(itself));
    memset(counters, 0, sizeof(counters));
    PyObject *result = NULL;
    if (check_nargs(nargs, 6, "lost_runs") < 0) return NULL;
    Py_ssize_t n = leading(args[0], "sending");
    if (n < 0) return NULL;
    if (bytes_get(args[0], &sending, n, 0, "sending") < 0) goto done;
    if (bytes_get(args[1], &answered, n, 0, "answered") < 0) goto done;
    if (bytes_get(args[2], &itself, n, 0, "robot_answers") < 0) goto done;
    for (int k = 0; k < 3; k++)
        if (int64s_get(args[3 + k], &counters[k], n, 1, names[k]) < 0) goto done;
    int open = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (BYTE1(sending, i))
            run_law(BYTE1(answered, i) || BYTE1(itself, i), &INT64_AT(counters[1], i),
                    &INT64_AT(counters[0], i), &INT64_AT(counters[2], i));
        open |= INT64_AT(counters[1], i) != 0;
    }
    result = PyBool_FromLong(open);
done:
    bytes_release(&sending);
    bytes_release(&answered);
    bytes_release(&itself);
    for (int k = 0; k < 3; k++) int64s_release(&counters[k]);
    return result;
}

static PyMethodDef METHODS[] = {
    METHOD(close_cycle, "Close the open cycle: every robot's window, lost-cycle run and success rate."),
    METHOD(lost_runs, "A cycle of the env's links: the lost cycles and runs of the sending arms."),
    {NULL, NULL, 0, NULL},
};

KERNEL_MODULE(_accounting, "The lost-cycle accounting's rules, their only text (fci/accounting.py, envs/channel.py).")
