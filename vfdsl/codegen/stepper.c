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
 * an exact dict holding exactly the declared names with such values, params None, dt None or a
 * float -- with every number finite, q inside its admissible range and dt inside (0, dt_max]. For
 * anything else it returns NotImplemented without evaluating, and the caller runs the detailed
 * checks in Python (which explain what is wrong, or convert the values and call Stepper.run). So
 * this file never decides that a value is wrong: it only recognises values that are certainly right.
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
    if (PyArray_NDIM(a) != 1 || PyArray_TYPE(a) != NPY_DOUBLE || PyArray_DIM(a, 0) != n
        || !PyArray_ISALIGNED(a) || PyArray_ISBYTESWAPPED(a)) return 0;
    base = PyArray_BYTES(a);
    stride = PyArray_STRIDE(a, 0);
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

static void use_default_params(Stepper* s) {
  if (!s->p_is_default) {
    memcpy(s->data[P], PyArray_DATA((PyArrayObject*) s->p_default), s->size[P] * sizeof(double));
    s->p_is_default = 1;
  }
}

static PyObject* Stepper_step(Stepper* s, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  PyObject *q, *inputs = NULL, *params = NULL, *dt = NULL, *result;
  double dt_value;
  if (kwnames || nargs < 1 || nargs > 4) Py_RETURN_NOTIMPLEMENTED;
  q = args[0];
  if (nargs > 1) inputs = args[1];
  if (nargs > 2) params = args[2];
  if (nargs > 3) dt = args[3];
  if (params != NULL && params != Py_None) Py_RETURN_NOTIMPLEMENTED;
  lock(s);
  if (!plain_vector(q, s->size[Q], s->data[Q]) || !q_admissible(s) || !plain_inputs(s, inputs)
      || !plain_dt(s, dt, &dt_value)) {
    PyThread_release_lock(s->lock);
    Py_RETURN_NOTIMPLEMENTED;
  }
  use_default_params(s);
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

/* ------------------------------------------------------------------------------- construction */

static int Stepper_init(Stepper* s, PyObject* args, PyObject* kwds) {
  PyObject *arrays, *names, *offsets, *sizes;
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  Py_ssize_t k, n;
  if (!PyArg_ParseTuple(args, "O!O!O!O!O!O!dd", &PyTuple_Type, &arrays, &PyArray_Type, &s->p_default,
                        &PyTuple_Type, &names, &PyTuple_Type, &offsets, &PyTuple_Type, &sizes,
                        &PyArray_Type, &s->q_range, &s->dt_default, &s->dt_max)) return -1;
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
  n = PyTuple_GET_SIZE(names);
  if (PyTuple_GET_SIZE(offsets) != n || PyTuple_GET_SIZE(sizes) != n
      || PyArray_SIZE((PyArrayObject*) s->p_default) != s->size[P]
      || PyArray_TYPE((PyArrayObject*) s->p_default) != NPY_DOUBLE
      || PyArray_SIZE((PyArrayObject*) s->q_range) != 2 * s->size[Q]
      || PyArray_TYPE((PyArrayObject*) s->q_range) != NPY_DOUBLE) {
    PyErr_SetString(PyExc_ValueError, "Stepper: inconsistent layout");
    return -1;
  }
  s->offsets = (Py_ssize_t*) calloc(n + 1, sizeof(Py_ssize_t));
  s->sizes = (Py_ssize_t*) calloc(n + 1, sizeof(Py_ssize_t));
  if (!s->offsets || !s->sizes) { PyErr_NoMemory(); return -1; }
  for (k=0; k<n; ++k) {
    s->offsets[k] = PyLong_AsSsize_t(PyTuple_GET_ITEM(offsets, k));
    s->sizes[k] = PyLong_AsSsize_t(PyTuple_GET_ITEM(sizes, k));
    if (PyErr_Occurred()) return -1;
    if (!PyUnicode_Check(PyTuple_GET_ITEM(names, k)) || s->offsets[k] < 0 || s->sizes[k] < 0
        || s->offsets[k] + s->sizes[k] > s->size[U]) {
      PyErr_SetString(PyExc_ValueError, "Stepper: inconsistent input layout");
      return -1;
    }
  }
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
  Py_INCREF(s->p_default);
  Py_INCREF(s->q_range);
  s->p_is_default = 0;
  return 0;
}

static void Stepper_dealloc(Stepper* s) {
  if (s->slot >= 0) VF_RELEASE(s->slot);
  if (s->lock) PyThread_free_lock(s->lock);
  free(s->arg); free(s->res); free(s->iw); free(s->w); free(s->offsets); free(s->sizes);
  if (s->arrays) {               /* the references below were taken only when init succeeded */
    Py_DECREF(s->arrays);
    Py_DECREF(s->names);
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
