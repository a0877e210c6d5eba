/* vfdsl: a Python extension type around one task's generated step function.
 *
 * Compiled together with the generated C of a task (build.py), with -DVFDSL_PREFIX=<the task's C
 * symbol> -DVFDSL_MODULE=<module name> and -include <prefix>.h. The task-specific layout (input
 * names, offsets and sizes, the joints' admissible range, the default params and period) is handed
 * over by the Python side when a Stepper is made, so this file is the same for every task. The
 * checks and the evaluation are checked_step.h's, the same code as the C library of `vfdsl export`.
 *
 * A Stepper owns one memory slot of the generated code (its solver workspaces and warm start), its
 * work arrays, and a lock: one Stepper used from two threads is serialised, Steppers of one task in
 * different threads run in parallel (the GIL is released during the solve).
 *
 * Stepper.step(q, inputs=None, params=None, dt=None) is Controller.step on the generated path (the Controller
 * makes it its own step: no Python call in between, ~0.1 us a tick). Its fast path accepts only the plainest
 * arguments, given by position or by keyword -- q a list/tuple of exact Python floats/ints (or NumPy float64 scalars)
 * or a 1-D float64 array, inputs an exact dict of exact str keys holding exactly the declared names with such values,
 * params None or an exact dict of run-time param names with such values (a run-time curve only as an N x 3 float64
 * array, a scalar also as a number), dt None or such a number -- with every number finite, q inside its admissible
 * range, dt inside the task's [dt_min, dt_max] and every check of the params holding (checked_step.h). For anything
 * else it evaluates nothing and hands the call to ``Stepper.checked`` (checked(stepper, q, inputs, params, dt), set by
 * vfdsl.runtime.native: the detailed checks in Python, which explain what is wrong, from the same column, or convert
 * the values and call Stepper.run), or returns NotImplemented when that is None. So this file never decides that a
 * value is wrong: it only recognises values that are certainly right. Nothing on the fast path allocates memory
 * but the returned dq, and no user code runs while it holds the lock (no float subclass's __float__, no key's __eq__:
 * such values go to the checks).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <structmember.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include "checked_step.h"
#ifdef VFDSL_PROCEDURE
#include "procedure_tick.h"
#endif

#define VF_STR_(a) #a
#define VF_STR(a) VF_STR_(a)

enum { Q = VFDSL_Q, U = VFDSL_U, P = VFDSL_P, X = VFDSL_X, N_ARRAYS = VFDSL_N_BUFFERS };

/* Each buffer's length in the generated step (the generated header's VFDSL_BUFFERS), in slot order. */
#define VF_LENGTH(slot, name, length) length,
static const Py_ssize_t buffer_lengths[N_ARRAYS] = {VFDSL_BUFFERS(VF_LENGTH)};
#undef VF_LENGTH

typedef struct {
  PyObject_HEAD
  vfdsl_core core;              /* slot, work arrays, and the N_ARRAYS buffers below */
  PyThread_type_lock lock;
  PyObject* arrays;             /* tuple of the N_ARRAYS float64 arrays of core.data (kept alive) */
  PyObject* p_default;          /* float64 array */
  int p_is_default;             /* data[P] holds the default params */
  PyObject* names;              /* tuple of the input names (str) */
  Py_ssize_t* offsets;
  Py_ssize_t* sizes;
  PyObject* param_names;        /* tuple of the run-time param names (str) */
  Py_ssize_t* param_offsets;
  Py_ssize_t* param_sizes;
  int* param_points;            /* 1 where the param is a run-time curve (N x 3 points) */
  int init_called;              /* __init__ runs once (a second call is refused before it touches anything) */
  PyObject* strict;             /* uint8 array: 1 where a check's margin must be > 0 */
  PyObject* q_range;            /* float64 array [lo_0..lo_n-1, hi_0..hi_n-1] of admissible q */
  double dt_default;            /* NAN when the task has no default period */
  PyObject* checked;            /* checked(stepper, q, inputs, params, dt) for what the fast path does not take; None */
  double* incoming;             /* the fast path's q, u, p as read, copied to the buffers only when all of them pass:
                                   a refused call leaves the buffers (a procedure's captures in p) as they were */
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure procedure;    /* the machine before each solve (procedure_tick.h) */
  double activity[VFDSL_ACTIVITY_LENGTH];
#endif
} Stepper;

#include "stepper_values.h"       /* reading values: plain_number, plain_vector, ..., step_arguments */

/* ----------------------------------------------------------------------------------- one tick */

static void lock(Stepper* s) {
  if (!PyThread_acquire_lock(s->lock, NOWAIT_LOCK)) {
    Py_BEGIN_ALLOW_THREADS
    PyThread_acquire_lock(s->lock, WAIT_LOCK);
    Py_END_ALLOW_THREADS
  }
}

/* Evaluate on the buffers (lock held) and return dq as a new array, or NULL with an exception. */
static PyObject* solve(Stepper* s, double dt, double recover) {
  int flag;
  npy_intp nq = s->core.size[Q];
  PyObject* dq;
  Py_BEGIN_ALLOW_THREADS
  flag = vfdsl_core_eval(&s->core, dt, recover);
  Py_END_ALLOW_THREADS
  if (flag) {
    PyErr_Format(PyExc_RuntimeError, "generated step " VF_STR(VFDSL_PREFIX) " failed with code %d", flag);
    return NULL;
  }
  dq = PyArray_SimpleNew(1, &nq, NPY_DOUBLE);
  if (dq) memcpy(PyArray_DATA((PyArrayObject*) dq), s->core.data[X], nq * sizeof(double));
  return dq;
}

/* One tick on the checked buffers (lock held): a procedure's machine first (procedure_tick.h), then the solve. */
static PyObject* tick(Stepper* s, double dt) {
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure_tick(&s->procedure, s->core.data[Q], s->core.data[U], s->core.data[P], dt,
                       (int) s->core.data[VFDSL_STATUS][0], s->activity);
#endif
  return solve(s, dt, 0.0);
}

/* checked(s, *args, **kwargs) (the vectorcall args and kwnames of a call of step), or NotImplemented when checked is
 * None. */
static PyObject* hand_over(Stepper* s, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  PyObject *stack[9], **items = stack, *checked = s->checked, *result;
  Py_ssize_t k, total = nargs + (kwnames ? PyTuple_GET_SIZE(kwnames) : 0);
  if (checked == NULL || checked == Py_None) Py_RETURN_NOTIMPLEMENTED;
  if (total + 1 > 9 && !(items = PyMem_New(PyObject*, total + 1))) return PyErr_NoMemory();
  items[0] = (PyObject*) s;
  for (k=0; k<total; ++k) items[k + 1] = args[k];
  Py_INCREF(checked);           /* (another thread may replace s->checked while it runs) */
  result = PyObject_Vectorcall(checked, items, nargs + 1, kwnames);
  Py_DECREF(checked);
  if (items != stack) PyMem_Free(items);
  return result;
}

/* 1 when s was initialised (else a RuntimeError is set): a Stepper made without a successful __init__ has no
 * lock, slot nor layout. */
static int ready(Stepper* s) {
  if (s->arrays) return 1;
  PyErr_SetString(PyExc_RuntimeError, "this Stepper was not initialised");
  return 0;
}

static PyObject* Stepper_step(Stepper* s, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  PyObject *a[4], *q, *inputs, *params, *dt, *result;
  double dt_value, *q_in, *u_in, *p_in;
  if (!ready(s)) return NULL;
  if (!step_arguments(args, nargs, kwnames, a)) return hand_over(s, args, nargs, kwnames);
  q = a[0];
  inputs = a[1];
  params = a[2];
  dt = a[3];
  lock(s);
  q_in = s->incoming;
  u_in = q_in + s->core.size[Q];
  p_in = u_in + s->core.size[U];
  if (!plain_vector(q, s->core.size[Q], q_in, 0) || vfdsl_q_outside(&s->core, q_in) >= 0
      || !plain_inputs(s, inputs, u_in) || !plain_dt(s, dt, &dt_value) || !plain_params(s, params, p_in)) {
    PyThread_release_lock(s->lock);
    return hand_over(s, args, nargs, kwnames);
  }
  memcpy(s->core.data[Q], q_in, s->core.size[Q] * sizeof(double));
  memcpy(s->core.data[U], u_in, s->core.size[U] * sizeof(double));
  if (params == NULL || params == Py_None) {
    use_default_params(s);
  } else {
    memcpy(s->core.data[P], p_in, s->core.size[P] * sizeof(double));
    s->p_is_default = 0;
  }
  result = tick(s, dt_value);
  PyThread_release_lock(s->lock);
  return result;
}

/* Copy checked float64 arrays in = {q, u, p} (p None: the defaults) into the buffers and take the lock: 0, or -1
 * with an exception (the lock not taken). */
static int load(Stepper* s, PyObject* const* in) {
  PyObject *q = in[0], *u = in[1], *p = in[2];
  if (p != Py_None && !PyArray_Check(p)) {
    PyErr_SetString(PyExc_TypeError, "p must be an array or None");
    return -1;
  }
  PyArrayObject* arrays[3] = {(PyArrayObject*) q, (PyArrayObject*) u, (PyArrayObject*) p};
  int slots[3] = {Q, U, P};
  for (int k=0; k<3; ++k) {
    if (k == 2 && p == Py_None) continue;
    if (PyArray_TYPE(arrays[k]) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arrays[k])
        || PyArray_SIZE(arrays[k]) != s->core.size[slots[k]]) {
      PyErr_SetString(PyExc_ValueError, "run() takes contiguous float64 arrays of the task's sizes");
      return -1;
    }
  }
  lock(s);
  memcpy(s->core.data[Q], PyArray_DATA(arrays[0]), s->core.size[Q] * sizeof(double));
  memcpy(s->core.data[U], PyArray_DATA(arrays[1]), s->core.size[U] * sizeof(double));
  if (p == Py_None) {
    use_default_params(s);
  } else {
    memcpy(s->core.data[P], PyArray_DATA(arrays[2]), s->core.size[P] * sizeof(double));
    s->p_is_default = 0;
  }
  return 0;
}

/* run(q, u, p, dt, recover): checked float64 arrays (p None: the defaults) -> dq; a procedure's machine does not
 * advance (the priming ticks). */
static PyObject* Stepper_run(Stepper* s, PyObject* args) {
  PyObject *in[3], *result;
  double dt, recover;
  if (!ready(s)) return NULL;
  if (!PyArg_ParseTuple(args, "O!O!Odd", &PyArray_Type, &in[0], &PyArray_Type, &in[1], &in[2], &dt, &recover))
    return NULL;
  if (load(s, in) < 0) return NULL;
  result = solve(s, dt, recover);
  PyThread_release_lock(s->lock);
  return result;
}

/* prime(q, u, dt): the priming of vfdsl.runtime.controller.Controller._prime on checked float64 arrays (the default
 * params): the step with the least-violation phase forced, then without; a procedure's in each case of its step
 * (procedure_tick.h). */
static PyObject* Stepper_prime(Stepper* s, PyObject* args) {
  PyObject* in[3] = {0, 0, Py_None};
  double dt;
  int flag;
  if (!ready(s)) return NULL;
  if (!PyArg_ParseTuple(args, "O!O!d", &PyArray_Type, &in[0], &PyArray_Type, &in[1], &dt)) return NULL;
  if (load(s, in) < 0) return NULL;
  Py_BEGIN_ALLOW_THREADS
#ifdef VFDSL_PROCEDURE
  flag = vfdsl_procedure_prime(&s->procedure, &s->core, dt, s->activity);
#else
  flag = vfdsl_core_eval(&s->core, dt, 1.0);
  if (!flag) flag = vfdsl_core_eval(&s->core, dt, 0.0);
#endif
  Py_END_ALLOW_THREADS
  PyThread_release_lock(s->lock);
  if (flag) {
    PyErr_Format(PyExc_RuntimeError, "generated step " VF_STR(VFDSL_PREFIX) " failed with code %d", flag);
    return NULL;
  }
  Py_RETURN_NONE;
}

#ifdef VFDSL_PROCEDURE
#include "stepper_procedure.h"   /* Stepper.tick, .reset, .machine */
#endif

/* margins(p): the column of checks of the params p (a contiguous float64 array), as a new array. */
static PyObject* Stepper_margins(Stepper* s, PyObject* p) {
  PyObject* out;
  npy_intp n = s->core.n_margins;
  if (!ready(s)) return NULL;
  if (!PyArray_Check(p) || PyArray_TYPE((PyArrayObject*) p) != NPY_DOUBLE
      || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) p) || PyArray_SIZE((PyArrayObject*) p) != s->core.size[P]) {
    PyErr_SetString(PyExc_ValueError, "margins() takes a contiguous float64 array of the task's params");
    return NULL;
  }
  out = PyArray_SimpleNew(1, &n, NPY_DOUBLE);
  if (!out) return NULL;
  lock(s);
  vfdsl_first_failure(&s->core, (const double*) PyArray_DATA((PyArrayObject*) p));
  memcpy(PyArray_DATA((PyArrayObject*) out), s->core.margins, n * sizeof(double));
  PyThread_release_lock(s->lock);
  return out;
}

/* results() -> (x, status, violation, p, activity): copies of the last tick's results, its full params and (a
 * procedure's) activity, else None, taken under the lock: a tick in another thread comes before or after, never
 * between two of them. */
static PyObject* Stepper_results(Stepper* s, PyObject* unused) {
  int slots[4] = {X, VFDSL_STATUS, VFDSL_VIOLATION, P}, k;
  PyObject* copies[5] = {0, 0, 0, 0, 0};
  if (!ready(s)) return NULL;
  for (k=0; k<4; ++k) {
    npy_intp n = s->core.size[slots[k]];
    if (!(copies[k] = PyArray_SimpleNew(1, &n, NPY_DOUBLE))) goto failed;
  }
#ifdef VFDSL_PROCEDURE
  {
    npy_intp na = VFDSL_ACTIVITY_LENGTH;
    if (!(copies[4] = PyArray_SimpleNew(1, &na, NPY_DOUBLE))) goto failed;
  }
#else
  Py_INCREF(Py_None);
  copies[4] = Py_None;
#endif
  lock(s);
  for (k=0; k<4; ++k)
    memcpy(PyArray_DATA((PyArrayObject*) copies[k]), s->core.data[slots[k]], s->core.size[slots[k]] * sizeof(double));
#ifdef VFDSL_PROCEDURE
  memcpy(PyArray_DATA((PyArrayObject*) copies[4]), s->activity, VFDSL_ACTIVITY_LENGTH * sizeof(double));
#endif
  PyThread_release_lock(s->lock);
  return Py_BuildValue("NNNNN", copies[0], copies[1], copies[2], copies[3], copies[4]);
failed:
  for (k=0; k<5; ++k) Py_XDECREF(copies[k]);
  return NULL;
}

/* ------------------------------------------------------------------------------- construction */

/* Offsets and sizes (tuples of ints, one per name) of named parts of an array of ``bound`` numbers. */
static int read_layout(PyObject* names, PyObject* offsets, PyObject* sizes, Py_ssize_t bound,
                       Py_ssize_t** out_offsets, Py_ssize_t** out_sizes) {
  Py_ssize_t k, n = PyTuple_GET_SIZE(names);
  if (PyTuple_GET_SIZE(offsets) != n || PyTuple_GET_SIZE(sizes) != n) goto inconsistent;
  *out_offsets = (Py_ssize_t*) calloc(n + 1, sizeof(Py_ssize_t));
  *out_sizes = (Py_ssize_t*) calloc(n + 1, sizeof(Py_ssize_t));
  if (!*out_offsets || !*out_sizes) { PyErr_NoMemory(); return -1; }
  for (k=0; k<n; ++k) {
    Py_ssize_t offset = PyLong_AsSsize_t(PyTuple_GET_ITEM(offsets, k));
    Py_ssize_t size = PyLong_AsSsize_t(PyTuple_GET_ITEM(sizes, k));
    if (PyErr_Occurred()) return -1;
    if (!PyUnicode_Check(PyTuple_GET_ITEM(names, k)) || offset < 0 || size < 0 || offset + size > bound)
      goto inconsistent;
    (*out_offsets)[k] = offset;
    (*out_sizes)[k] = size;
  }
  return 0;
inconsistent:
  PyErr_SetString(PyExc_ValueError, "Stepper: inconsistent input or param layout");
  return -1;
}

/* Stepper(arrays, p_default, input names, offsets, sizes, q_range, dt_default, dt_min, dt_max,
 *         param names, offsets, sizes, points, strict) */
static int Stepper_init(Stepper* s, PyObject* args, PyObject* kwds) {
  PyObject *arrays, *names, *offsets, *sizes, *param_names, *param_offsets, *param_sizes, *points;
  Py_ssize_t k;
  int opened;
  if (s->init_called) {
    PyErr_SetString(PyExc_RuntimeError, "Stepper is initialised once");
    return -1;
  }
  s->init_called = 1;
  if (!PyArg_ParseTuple(args, "O!O!O!O!O!O!dddO!O!O!O!O!", &PyTuple_Type, &arrays, &PyArray_Type, &s->p_default,
                        &PyTuple_Type, &names, &PyTuple_Type, &offsets, &PyTuple_Type, &sizes, &PyArray_Type,
                        &s->q_range, &s->dt_default, &s->core.dt_min, &s->core.dt_max, &PyTuple_Type, &param_names,
                        &PyTuple_Type, &param_offsets, &PyTuple_Type, &param_sizes, &PyTuple_Type, &points,
                        &PyArray_Type, &s->strict))
    return -1;
  if (PyTuple_GET_SIZE(arrays) != N_ARRAYS) {
    PyErr_Format(PyExc_ValueError, "Stepper needs %d arrays: %s", (int) N_ARRAYS, VFDSL_BUFFER_NAMES);
    return -1;
  }
  for (k=0; k<N_ARRAYS; ++k) {
    PyObject* a = PyTuple_GET_ITEM(arrays, k);
    if (!PyArray_Check(a) || PyArray_TYPE((PyArrayObject*) a) != NPY_DOUBLE
        || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) a) || !PyArray_ISWRITEABLE((PyArrayObject*) a)) {
      PyErr_SetString(PyExc_ValueError, "Stepper's arrays must be writeable contiguous float64 arrays");
      return -1;
    }
    if (PyArray_SIZE((PyArrayObject*) a) != buffer_lengths[k]) {
      PyErr_Format(PyExc_ValueError, "Stepper's array %zd (of %s) has %zd numbers, the generated step's %zd", k,
                   VFDSL_BUFFER_NAMES, (Py_ssize_t) PyArray_SIZE((PyArrayObject*) a), buffer_lengths[k]);
      return -1;
    }
    s->core.data[k] = (double*) PyArray_DATA((PyArrayObject*) a);
    s->core.size[k] = PyArray_SIZE((PyArrayObject*) a);
  }
  if (PyArray_SIZE((PyArrayObject*) s->p_default) != s->core.size[P]
      || PyArray_TYPE((PyArrayObject*) s->p_default) != NPY_DOUBLE
      || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) s->p_default)
      || PyArray_SIZE((PyArrayObject*) s->q_range) != 2 * s->core.size[Q]
      || PyArray_TYPE((PyArrayObject*) s->q_range) != NPY_DOUBLE
      || PyArray_TYPE((PyArrayObject*) s->strict) != NPY_UINT8
      || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) s->strict)) {
    PyErr_SetString(PyExc_ValueError, "Stepper: inconsistent layout");
    return -1;
  }
  if (read_layout(names, offsets, sizes, s->core.size[U], &s->offsets, &s->sizes) < 0
      || read_layout(param_names, param_offsets, param_sizes, s->core.size[P], &s->param_offsets, &s->param_sizes) < 0)
    return -1;
  if (PyTuple_GET_SIZE(points) != PyTuple_GET_SIZE(param_names)) {
    PyErr_SetString(PyExc_ValueError, "Stepper: one 'points' flag per param");
    return -1;
  }
  s->param_points = (int*) calloc(PyTuple_GET_SIZE(points) + 1, sizeof(int));
  s->incoming = (double*) calloc(s->core.size[Q] + s->core.size[U] + s->core.size[P] + 1, sizeof(double));
  if (!s->param_points || !s->incoming) { PyErr_NoMemory(); return -1; }
  for (k=0; k<PyTuple_GET_SIZE(points); ++k) s->param_points[k] = PyTuple_GET_ITEM(points, k) == Py_True;
  s->core.q_lower = (const double*) PyArray_DATA((PyArrayObject*) s->q_range);
  s->core.q_upper = s->core.q_lower + s->core.size[Q];
  s->core.strict = (const unsigned char*) PyArray_DATA((PyArrayObject*) s->strict);
  s->core.n_margins = PyArray_SIZE((PyArrayObject*) s->strict);
  s->lock = PyThread_allocate_lock();
#ifdef VFDSL_PROCEDURE
  s->core.activity = s->activity;
  if (vfdsl_procedure_open(&s->procedure, s->activity) != VFDSL_OPENED) { PyErr_NoMemory(); return -1; }
#endif
  opened = vfdsl_core_open(&s->core);
  if (opened == VFDSL_NO_MEMORY || !s->lock) { PyErr_NoMemory(); return -1; }
  if (opened == VFDSL_NO_SLOT) {
    PyErr_SetString(PyExc_RuntimeError, "all memory slots of " VF_STR(VFDSL_PREFIX) " are in use");
    return -1;
  }
  Py_INCREF(arrays); s->arrays = arrays;
  Py_INCREF(names); s->names = names;
  Py_INCREF(param_names); s->param_names = param_names;
  Py_INCREF(s->strict);
  Py_INCREF(s->p_default);
  Py_INCREF(s->q_range);
  Py_INCREF(Py_None); s->checked = Py_None;
  s->p_is_default = 0;
  return 0;
}

static void Stepper_dealloc(Stepper* s) {
  vfdsl_core_close(&s->core);
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure_close(&s->procedure);
#endif
  if (s->lock) PyThread_free_lock(s->lock);
  free(s->offsets); free(s->sizes); free(s->param_offsets); free(s->param_sizes); free(s->param_points);
  free(s->incoming);
  if (s->arrays) {               /* the references below were taken only when init succeeded */
    Py_DECREF(s->arrays);
    Py_DECREF(s->names);
    Py_DECREF(s->param_names);
    Py_DECREF(s->strict);
    Py_DECREF(s->p_default);
    Py_DECREF(s->q_range);
  }
  Py_XDECREF(s->checked);
  Py_TYPE(s)->tp_free((PyObject*) s);
}

static PyObject* Stepper_new(PyTypeObject* type, PyObject* args, PyObject* kwds) {
  Stepper* s = (Stepper*) type->tp_alloc(type, 0);
  if (s) s->core.slot = -1;
  return (PyObject*) s;
}

static PyObject* Stepper_get_slot(Stepper* s, void* closure) {
  return PyLong_FromLong(s->core.slot);
}

static PyMethodDef Stepper_methods[] = {
  {"step", (PyCFunction) (void (*)(void)) Stepper_step, METH_FASTCALL | METH_KEYWORDS,
   "step(q, inputs=None, params=None, dt=None) -> dq: the joint increment for this tick (SI), as "
   "vfdsl.runtime.controller.Controller.step documents. Plain values (lists, tuples or float64 arrays of finite "
   "numbers, exact dicts), by position or keyword, are checked here; anything else goes to the detailed checks of "
   "``checked`` (which explain what is wrong), or gives NotImplemented when ``checked`` is None."},
  {"margins", (PyCFunction) Stepper_margins, METH_O,
   "margins(p) -> the column of checks of the params p (contiguous float64), from the generated C"},
  {"run", (PyCFunction) Stepper_run, METH_VARARGS,
   "run(q, u, p, dt, recover) -> dq for checked float64 arrays (p None: the default params)"},
  {"results", (PyCFunction) Stepper_results, METH_NOARGS,
   "results() -> (x, status, violation, p, activity or None): copies of the last tick's, taken under the lock"},
  {"prime", (PyCFunction) Stepper_prime, METH_VARARGS,
   "prime(q, u, dt): every solver's workspace allocated (the step with and without recovery; a procedure's in "
   "each case of its step), on checked float64 arrays and the default params"},
#ifdef VFDSL_PROCEDURE
  {"tick", (PyCFunction) Stepper_tick, METH_VARARGS,
   "tick(q, u, p, dt) -> dq for checked float64 arrays (p None: the default params): the procedure's machine, "
   "then the solve"},
  {"reset", (PyCFunction) Stepper_reset, METH_NOARGS, "reset(): the procedure back to its initial phase"},
  {"machine", (PyCFunction) Stepper_machine, METH_NOARGS,
   "machine() -> (phase, source, fired, time, activity, monitor values) after the last tick"},
#endif
  {NULL, NULL, 0, NULL}
};

static PyMemberDef Stepper_members[] = {
  {"checked", T_OBJECT, offsetof(Stepper, checked), 0,
   "checked(stepper, q, inputs, params, dt) -> dq: step's detailed checks for what its fast path does not take "
   "(None: step returns NotImplemented instead). It must not hold the Stepper (no reference cycle)."},
  {NULL, 0, 0, 0, NULL}
};

static PyGetSetDef Stepper_getset[] = {
  {"slot", (getter) Stepper_get_slot, NULL, "the memory slot of the generated code", NULL},
  {NULL, NULL, NULL, NULL, NULL}
};

static PyTypeObject StepperType = {
  PyVarObject_HEAD_INIT(NULL, 0)
  .tp_name = VF_STR(VFDSL_MODULE) ".Stepper",
  .tp_basicsize = sizeof(Stepper),
  .tp_flags = Py_TPFLAGS_DEFAULT,
  .tp_doc = "One controller's evaluation of the generated step: own memory slot, work arrays, lock.",
  .tp_new = Stepper_new,
  .tp_init = (initproc) Stepper_init,
  .tp_dealloc = (destructor) Stepper_dealloc,
  .tp_methods = Stepper_methods,
  .tp_getset = Stepper_getset,
  .tp_members = Stepper_members,
};

static struct PyModuleDef module = {
  PyModuleDef_HEAD_INIT, VF_STR(VFDSL_MODULE), "The generated step of one vfdsl task.", -1, NULL,
};

PyMODINIT_FUNC VFDSL_CAT(PyInit_, VFDSL_MODULE)(void) {
  static const char* const keywords[4] = {"q", "inputs", "params", "dt"};
  PyObject* m;
  int i;
  import_array();
  for (i=0; i<4; ++i)
    if (!step_keywords[i] && !(step_keywords[i] = PyUnicode_InternFromString(keywords[i]))) return NULL;
  if (PyType_Ready(&StepperType) < 0) return NULL;
  m = PyModule_Create(&module);
  if (!m) return NULL;
  Py_INCREF(&StepperType);
  if (PyModule_AddObject(m, "Stepper", (PyObject*) &StepperType) < 0) {
    Py_DECREF(&StepperType);
    Py_DECREF(m);
    return NULL;
  }
  return m;
}
