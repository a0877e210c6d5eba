/* vfdsl: a Python extension type around one task's generated step function.
 *
 * Compiled together with the generated C of a task (build.py), with -DVFDSL_PREFIX=<the task's C
 * symbol> -DVFDSL_MODULE=<module name> and -include <prefix>.h. The task-specific layout (input
 * names, offsets and sizes, the joints' admissible range, the default params and period) is handed
 * over by the Python side when a Stepper is made, so this file is the same for every task.
 *
 * A Stepper owns one memory slot of the generated code (its solver workspaces and warm start), its
 * work arrays, and a lock: one Stepper used from two threads is serialised, Steppers of one task in
 * different threads run in parallel (the GIL is released during the solve).
 *
 * Stepper.step(q, inputs=None, params=None, dt=None) is the fast path of Controller.step: it accepts
 * only the plainest arguments -- q a list/tuple of Python floats/ints or a 1-D float64 array, inputs
 * an exact dict holding exactly the declared names with such values, params None or an exact dict of
 * run-time param names with such values (a run-time curve also as an N x 3 float64 array, a scalar
 * also as a number), dt None or a float -- with every number finite, q inside its admissible range,
 * dt inside (0, dt_max] and every check of the params holding: the generated <prefix>_admissible
 * evaluates the task's column of margins (vfdsl.compiler.admissible) and check i holds iff margin i is
 * finite and >= 0 (> 0 where strict[i]). For anything else it returns NotImplemented without
 * evaluating, and the caller runs the detailed checks in Python (which explain what is wrong, from the
 * same column, or convert the values and call Stepper.run). So this file never decides that a value is
 * wrong: it only recognises values that are certainly right. Nothing on the fast path allocates memory
 * but the returned dq.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define VF_CAT_(a, b) a##b
#define VF_CAT(a, b) VF_CAT_(a, b)
#define VF_STR_(a) #a
#define VF_STR(a) VF_STR_(a)
#define VF_EVAL VFDSL_PREFIX
#define VF_CHECKOUT VF_CAT(VFDSL_PREFIX, _checkout)
#define VF_RELEASE VF_CAT(VFDSL_PREFIX, _release)
#define VF_WORK VF_CAT(VFDSL_PREFIX, _work)
#define VF_ADMISSIBLE VF_CAT(VFDSL_PREFIX, _admissible)
#define VF_ADMISSIBLE_WORK VF_CAT(VFDSL_PREFIX, _admissible_work)

enum { Q, U, P, DT, RECOVER, X, STATUS, VIOLATION, N_ARRAYS };

typedef struct {
  PyObject_HEAD
  int slot;                     /* memory slot of the generated code, -1 when none */
  PyThread_type_lock lock;
  PyObject* arrays;             /* tuple of the N_ARRAYS float64 arrays below (kept alive) */
  double* data[N_ARRAYS];
  Py_ssize_t size[N_ARRAYS];
  PyObject* p_default;          /* float64 array */
  int p_is_default;             /* data[P] holds the default params */
  PyObject* names;              /* tuple of the input names (str) */
  Py_ssize_t* offsets;
  Py_ssize_t* sizes;
  PyObject* param_names;        /* tuple of the run-time param names (str) */
  Py_ssize_t* param_offsets;
  Py_ssize_t* param_sizes;
  PyObject* strict;             /* uint8 array: 1 where a check's margin must be > 0 */
  Py_ssize_t n_margins;
  double* margins;
  const casadi_real** check_arg;
  casadi_real** check_res;
  casadi_int* check_iw;
  casadi_real* check_w;
  PyObject* q_range;            /* float64 array [lo_0..lo_n-1, hi_0..hi_n-1] of admissible q */
  double dt_default;            /* NAN when the task has no default period */
  double dt_max;
  const casadi_real** arg;
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
} Stepper;

/* ------------------------------------------------------------------------------ reading values */

/* 1 when ``value`` is a finite real written as a Python float or int (not bool), stored in *out. */
static int plain_number(PyObject* value, double* out) {
  if (PyFloat_Check(value)) {
    *out = PyFloat_AS_DOUBLE(value);
  } else if (PyLong_CheckExact(value)) {
    *out = PyLong_AsDouble(value);
    if (*out == -1.0 && PyErr_Occurred()) { PyErr_Clear(); return 0; }
  } else {
    return 0;
  }
  return isfinite(*out);
}

/* 1 when ``value`` is n plain finite numbers (list, tuple or 1-D float64 array), copied to out. */
static int plain_vector(PyObject* value, Py_ssize_t n, double* out) {
  Py_ssize_t i;
  if (PyList_CheckExact(value) || PyTuple_CheckExact(value)) {
    PyObject** items;
    if (PySequence_Fast_GET_SIZE(value) != n) return 0;
    items = PySequence_Fast_ITEMS(value);
    for (i=0; i<n; ++i) if (!plain_number(items[i], out + i)) return 0;
    return 1;
  }
  if (PyArray_CheckExact(value)) {
    PyArrayObject* a = (PyArrayObject*) value;
    const char* base;
    npy_intp stride;
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_ISALIGNED(a) || PyArray_ISBYTESWAPPED(a)) return 0;
    if (PyArray_NDIM(a) == 1 && PyArray_DIM(a, 0) == n) {
      stride = PyArray_STRIDE(a, 0);
    } else if (PyArray_NDIM(a) == 2 && PyArray_DIM(a, 1) == 3 && 3 * PyArray_DIM(a, 0) == n
               && PyArray_IS_C_CONTIGUOUS(a)) {      /* points, one a row */
      stride = sizeof(double);
    } else {
      return 0;
    }
    base = PyArray_BYTES(a);
    for (i=0; i<n; ++i) {
      out[i] = *(const double*) (base + i*stride);
      if (!isfinite(out[i])) return 0;
    }
    return 1;
  }
  return 0;
}

static int plain_inputs(Stepper* s, PyObject* inputs) {
  Py_ssize_t k, n = PyTuple_GET_SIZE(s->names);
  if (inputs == Py_None || inputs == NULL) return n == 0;
  if (!PyDict_CheckExact(inputs) || PyDict_GET_SIZE(inputs) != n) return 0;
  for (k=0; k<n; ++k) {
    PyObject* value = PyDict_GetItemWithError(inputs, PyTuple_GET_ITEM(s->names, k));
    if (value == NULL) { PyErr_Clear(); return 0; }
    if (!plain_vector(value, s->sizes[k], s->data[U] + s->offsets[k])) return 0;
  }
  return 1;
}

static void use_default_params(Stepper* s) {
  if (!s->p_is_default) {
    memcpy(s->data[P], PyArray_DATA((PyArrayObject*) s->p_default), s->size[P] * sizeof(double));
    s->p_is_default = 1;
  }
}

/* The index of the first check of the params in data[P] that fails, or -1 (evaluates the column). */
static int first_failure(Stepper* s, const double* p) {
  const unsigned char* strict = (const unsigned char*) PyArray_DATA((PyArrayObject*) s->strict);
  Py_ssize_t i;
  s->check_arg[0] = p;
  s->check_res[0] = s->margins;
  if (VF_ADMISSIBLE(s->check_arg, s->check_res, s->check_iw, s->check_w, 0)) return 0;
  for (i=0; i<s->n_margins; ++i) {
    double m = s->margins[i];
    if (!isfinite(m) || !(strict[i] ? m > 0 : m >= 0)) return (int) i;
  }
  return -1;
}

/* 1 when ``params`` is None, or an exact dict of run-time param names with plain values (copied over the
 * defaults in data[P]) that pass every check. */
static int plain_params(Stepper* s, PyObject* params) {
  Py_ssize_t pos = 0, k, n = PyTuple_GET_SIZE(s->param_names);
  PyObject *key, *value;
  if (params == NULL || params == Py_None) {
    use_default_params(s);
    return 1;
  }
  if (!PyDict_CheckExact(params)) return 0;
  memcpy(s->data[P], PyArray_DATA((PyArrayObject*) s->p_default), s->size[P] * sizeof(double));
  s->p_is_default = 0;
  while (PyDict_Next(params, &pos, &key, &value)) {
    double* out;
    if (!PyUnicode_CheckExact(key)) return 0;
    for (k=0; k<n; ++k) {
      PyObject* name = PyTuple_GET_ITEM(s->param_names, k);
      if (name == key || PyUnicode_Compare(name, key) == 0) break;
    }
    if (k == n) return 0;
    out = s->data[P] + s->param_offsets[k];
    if (s->param_sizes[k] == 1 && !PyList_CheckExact(value) && !PyTuple_CheckExact(value)
        && !PyArray_CheckExact(value)) {
      if (!plain_number(value, out)) return 0;
    } else if (!plain_vector(value, s->param_sizes[k], out)) {
      return 0;
    }
  }
  return first_failure(s, s->data[P]) < 0;
}

static int plain_dt(Stepper* s, PyObject* dt, double* out) {
  if (dt == Py_None || dt == NULL) *out = s->dt_default;
  else if (!plain_number(dt, out)) return 0;
  return *out > 0 && *out <= s->dt_max;   /* false for NAN (no default period) */
}

static int q_admissible(Stepper* s) {
  const double* range = (const double*) PyArray_DATA((PyArrayObject*) s->q_range);
  Py_ssize_t i, n = s->size[Q];
  for (i=0; i<n; ++i) {
    if (!(s->data[Q][i] >= range[i] && s->data[Q][i] <= range[n + i])) return 0;
  }
  return 1;
}

/* ----------------------------------------------------------------------------------- one tick */

static void lock(Stepper* s) {
  if (!PyThread_acquire_lock(s->lock, NOWAIT_LOCK)) {
    Py_BEGIN_ALLOW_THREADS
    PyThread_acquire_lock(s->lock, WAIT_LOCK);
    Py_END_ALLOW_THREADS
  }
}

/* Evaluate on the buffers (lock held) and return dq as a new array, or NULL with an exception. */
static PyObject* solve(Stepper* s) {
  int flag;
  npy_intp nq = s->size[Q];
  PyObject* dq;
  Py_BEGIN_ALLOW_THREADS
  flag = VF_EVAL(s->arg, s->res, s->iw, s->w, s->slot);
  Py_END_ALLOW_THREADS
  if (flag) {
    PyErr_Format(PyExc_RuntimeError, "generated step " VF_STR(VFDSL_PREFIX) " failed with code %d", flag);
    return NULL;
  }
  dq = PyArray_SimpleNew(1, &nq, NPY_DOUBLE);
  if (dq) memcpy(PyArray_DATA((PyArrayObject*) dq), s->data[X], nq * sizeof(double));
  return dq;
}

static PyObject* Stepper_step(Stepper* s, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  PyObject *q, *inputs = NULL, *params = NULL, *dt = NULL, *result;
  double dt_value;
  if (kwnames || nargs < 1 || nargs > 4) Py_RETURN_NOTIMPLEMENTED;
  q = args[0];
  if (nargs > 1) inputs = args[1];
  if (nargs > 2) params = args[2];
  if (nargs > 3) dt = args[3];
  lock(s);
  if (!plain_vector(q, s->size[Q], s->data[Q]) || !q_admissible(s) || !plain_inputs(s, inputs)
      || !plain_dt(s, dt, &dt_value) || !plain_params(s, params)) {
    PyThread_release_lock(s->lock);
    Py_RETURN_NOTIMPLEMENTED;
  }
  s->data[DT][0] = dt_value;
  s->data[RECOVER][0] = 0.0;
  result = solve(s);
  PyThread_release_lock(s->lock);
  return result;
}

/* run(q, u, p, dt, recover): checked float64 arrays (p None: the defaults) -> dq. */
static PyObject* Stepper_run(Stepper* s, PyObject* args) {
  PyObject *q, *u, *p, *result;
  double dt, recover;
  if (!PyArg_ParseTuple(args, "O!O!Odd", &PyArray_Type, &q, &PyArray_Type, &u, &p, &dt, &recover)) return NULL;
  if (p != Py_None && !PyArray_Check(p)) {
    PyErr_SetString(PyExc_TypeError, "p must be an array or None");
    return NULL;
  }
  PyArrayObject* arrays[3] = {(PyArrayObject*) q, (PyArrayObject*) u, (PyArrayObject*) p};
  int slots[3] = {Q, U, P};
  for (int k=0; k<3; ++k) {
    if (k == 2 && p == Py_None) continue;
    if (PyArray_TYPE(arrays[k]) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arrays[k])
        || PyArray_SIZE(arrays[k]) != s->size[slots[k]]) {
      PyErr_SetString(PyExc_ValueError, "run() takes contiguous float64 arrays of the task's sizes");
      return NULL;
    }
  }
  lock(s);
  memcpy(s->data[Q], PyArray_DATA(arrays[0]), s->size[Q] * sizeof(double));
  memcpy(s->data[U], PyArray_DATA(arrays[1]), s->size[U] * sizeof(double));
  if (p == Py_None) {
    use_default_params(s);
  } else {
    memcpy(s->data[P], PyArray_DATA(arrays[2]), s->size[P] * sizeof(double));
    s->p_is_default = 0;
  }
  s->data[DT][0] = dt;
  s->data[RECOVER][0] = recover;
  result = solve(s);
  PyThread_release_lock(s->lock);
  return result;
}

/* margins(p): the column of checks of the params p (a contiguous float64 array), as a new array. */
static PyObject* Stepper_margins(Stepper* s, PyObject* p) {
  PyObject* out;
  npy_intp n = s->n_margins;
  if (!PyArray_Check(p) || PyArray_TYPE((PyArrayObject*) p) != NPY_DOUBLE
      || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) p) || PyArray_SIZE((PyArrayObject*) p) != s->size[P]) {
    PyErr_SetString(PyExc_ValueError, "margins() takes a contiguous float64 array of the task's params");
    return NULL;
  }
  out = PyArray_SimpleNew(1, &n, NPY_DOUBLE);
  if (!out) return NULL;
  lock(s);
  first_failure(s, (const double*) PyArray_DATA((PyArrayObject*) p));
  memcpy(PyArray_DATA((PyArrayObject*) out), s->margins, n * sizeof(double));
  PyThread_release_lock(s->lock);
  return out;
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

/* Stepper(arrays, p_default, input names, offsets, sizes, q_range, dt_default, dt_max,
 *         param names, offsets, sizes, strict) */
static int Stepper_init(Stepper* s, PyObject* args, PyObject* kwds) {
  PyObject *arrays, *names, *offsets, *sizes, *param_names, *param_offsets, *param_sizes;
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  Py_ssize_t k;
  if (!PyArg_ParseTuple(args, "O!O!O!O!O!O!ddO!O!O!O!", &PyTuple_Type, &arrays, &PyArray_Type, &s->p_default,
                        &PyTuple_Type, &names, &PyTuple_Type, &offsets, &PyTuple_Type, &sizes,
                        &PyArray_Type, &s->q_range, &s->dt_default, &s->dt_max, &PyTuple_Type, &param_names,
                        &PyTuple_Type, &param_offsets, &PyTuple_Type, &param_sizes, &PyArray_Type, &s->strict))
    return -1;
  if (s->arrays) {
    PyErr_SetString(PyExc_RuntimeError, "Stepper is initialised once");
    return -1;
  }
  if (PyTuple_GET_SIZE(arrays) != N_ARRAYS) {
    PyErr_SetString(PyExc_ValueError, "Stepper needs 8 arrays: q, u, p, dt, recover, x, status, violation");
    return -1;
  }
  for (k=0; k<N_ARRAYS; ++k) {
    PyObject* a = PyTuple_GET_ITEM(arrays, k);
    if (!PyArray_Check(a) || PyArray_TYPE((PyArrayObject*) a) != NPY_DOUBLE
        || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) a) || !PyArray_ISWRITEABLE((PyArrayObject*) a)) {
      PyErr_SetString(PyExc_ValueError, "Stepper's arrays must be writeable contiguous float64 arrays");
      return -1;
    }
    s->data[k] = (double*) PyArray_DATA((PyArrayObject*) a);
    s->size[k] = PyArray_SIZE((PyArrayObject*) a);
  }
  if (PyArray_SIZE((PyArrayObject*) s->p_default) != s->size[P]
      || PyArray_TYPE((PyArrayObject*) s->p_default) != NPY_DOUBLE
      || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) s->p_default)
      || PyArray_SIZE((PyArrayObject*) s->q_range) != 2 * s->size[Q]
      || PyArray_TYPE((PyArrayObject*) s->q_range) != NPY_DOUBLE
      || PyArray_TYPE((PyArrayObject*) s->strict) != NPY_UINT8
      || !PyArray_IS_C_CONTIGUOUS((PyArrayObject*) s->strict)) {
    PyErr_SetString(PyExc_ValueError, "Stepper: inconsistent layout");
    return -1;
  }
  if (read_layout(names, offsets, sizes, s->size[U], &s->offsets, &s->sizes) < 0
      || read_layout(param_names, param_offsets, param_sizes, s->size[P], &s->param_offsets, &s->param_sizes) < 0)
    return -1;
  VF_ADMISSIBLE_WORK(&sz_arg, &sz_res, &sz_iw, &sz_w);
  s->n_margins = PyArray_SIZE((PyArrayObject*) s->strict);
  s->check_arg = (const casadi_real**) calloc(sz_arg + 1, sizeof(casadi_real*));
  s->check_res = (casadi_real**) calloc(sz_res + 1, sizeof(casadi_real*));
  s->check_iw = (casadi_int*) calloc(sz_iw + 1, sizeof(casadi_int));
  s->check_w = (casadi_real*) calloc(sz_w + 1, sizeof(casadi_real));
  s->margins = (double*) calloc(s->n_margins + 1, sizeof(double));
  if (!s->check_arg || !s->check_res || !s->check_iw || !s->check_w || !s->margins) { PyErr_NoMemory(); return -1; }
  VF_WORK(&sz_arg, &sz_res, &sz_iw, &sz_w);
  s->arg = (const casadi_real**) calloc(sz_arg + 1, sizeof(casadi_real*));
  s->res = (casadi_real**) calloc(sz_res + 1, sizeof(casadi_real*));
  s->iw = (casadi_int*) calloc(sz_iw + 1, sizeof(casadi_int));
  s->w = (casadi_real*) calloc(sz_w + 1, sizeof(casadi_real));
  s->lock = PyThread_allocate_lock();
  if (!s->arg || !s->res || !s->iw || !s->w || !s->lock) { PyErr_NoMemory(); return -1; }
  for (k=0; k<=RECOVER; ++k) s->arg[k] = s->data[k];
  for (k=X; k<N_ARRAYS; ++k) s->res[k - X] = s->data[k];
  s->slot = VF_CHECKOUT();
  if (s->slot < 0) {
    PyErr_SetString(PyExc_RuntimeError, "all memory slots of " VF_STR(VFDSL_PREFIX) " are in use");
    return -1;
  }
  Py_INCREF(arrays); s->arrays = arrays;
  Py_INCREF(names); s->names = names;
  Py_INCREF(param_names); s->param_names = param_names;
  Py_INCREF(s->strict);
  Py_INCREF(s->p_default);
  Py_INCREF(s->q_range);
  s->p_is_default = 0;
  return 0;
}

static void Stepper_dealloc(Stepper* s) {
  if (s->slot >= 0) VF_RELEASE(s->slot);
  if (s->lock) PyThread_free_lock(s->lock);
  free(s->arg); free(s->res); free(s->iw); free(s->w); free(s->offsets); free(s->sizes);
  free(s->param_offsets); free(s->param_sizes); free(s->margins);
  free(s->check_arg); free(s->check_res); free(s->check_iw); free(s->check_w);
  if (s->arrays) {               /* the references below were taken only when init succeeded */
    Py_DECREF(s->arrays);
    Py_DECREF(s->names);
    Py_DECREF(s->param_names);
    Py_DECREF(s->strict);
    Py_DECREF(s->p_default);
    Py_DECREF(s->q_range);
  }
  Py_TYPE(s)->tp_free((PyObject*) s);
}

static PyObject* Stepper_new(PyTypeObject* type, PyObject* args, PyObject* kwds) {
  Stepper* s = (Stepper*) type->tp_alloc(type, 0);
  if (s) s->slot = -1;
  return (PyObject*) s;
}

static PyObject* Stepper_get_slot(Stepper* s, void* closure) {
  return PyLong_FromLong(s->slot);
}

static PyMethodDef Stepper_methods[] = {
  {"step", (PyCFunction) (void (*)(void)) Stepper_step, METH_FASTCALL | METH_KEYWORDS,
   "step(q, inputs=None, params=None, dt=None) -> dq, or NotImplemented when the arguments need the "
   "detailed checks"},
  {"margins", (PyCFunction) Stepper_margins, METH_O,
   "margins(p) -> the column of checks of the params p (contiguous float64), from the generated C"},
  {"run", (PyCFunction) Stepper_run, METH_VARARGS,
   "run(q, u, p, dt, recover) -> dq for checked float64 arrays (p None: the default params)"},
  {NULL, NULL, 0, NULL}
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
};

static struct PyModuleDef module = {
  PyModuleDef_HEAD_INIT, VF_STR(VFDSL_MODULE), "The generated step of one vfdsl task.", -1, NULL,
};

PyMODINIT_FUNC VF_CAT(PyInit_, VFDSL_MODULE)(void) {
  PyObject* m;
  import_array();
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
