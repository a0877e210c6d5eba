/* vfdsl: the fast path's reading of Python values, for stepper.c only (included there after the Stepper type): what
 * it recognises as certainly right (stepper.c's header says which values); anything else goes to the checks. */
#ifndef VFDSL_STEPPER_VALUES_H
#define VFDSL_STEPPER_VALUES_H

/* 1 when ``value`` is a finite real written as an exact Python float or int (not bool; no subclass, whose __float__
 * only the Python checks call) or a NumPy float64 scalar, stored in *out. */
static int plain_number(PyObject* value, double* out) {
  if (PyFloat_CheckExact(value) || Py_IS_TYPE(value, &PyDoubleArrType_Type)) {
    *out = PyFloat_AS_DOUBLE(value);
  } else if (PyLong_CheckExact(value)) {
    *out = PyLong_AsDouble(value);
    if (*out == -1.0 && PyErr_Occurred()) { PyErr_Clear(); return 0; }
  } else {
    return 0;
  }
  return isfinite(*out);
}

/* 1 when ``value`` is n plain finite numbers, copied to out: a list, tuple or 1-D float64 array, or, for points
 * (a run-time curve), only a C-contiguous float64 array of n / 3 rows [x, y, z] (the Python checks take the other
 * forms, and refuse a flat curve or a 2-D array elsewhere). */
static int plain_vector(PyObject* value, Py_ssize_t n, double* out, int points) {
  Py_ssize_t i;
  if (!points && (PyList_CheckExact(value) || PyTuple_CheckExact(value))) {
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
    if (!points && PyArray_NDIM(a) == 1 && PyArray_DIM(a, 0) == n) {
      stride = PyArray_STRIDE(a, 0);
    } else if (points && PyArray_NDIM(a) == 2 && PyArray_DIM(a, 1) == 3 && 3 * PyArray_DIM(a, 0) == n
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

/* 1 when ``inputs`` is an exact dict of every input's name (exact str keys) with plain values that pass every check,
 * copied to u (the inputs' buffer's layout). */
static int plain_inputs(Stepper* s, PyObject* inputs, double* u) {
  Py_ssize_t k, pos = 0, n = PyTuple_GET_SIZE(s->names);
  PyObject *key, *value;
  if (inputs == Py_None || inputs == NULL) return n == 0;
  if (!PyDict_CheckExact(inputs) || PyDict_GET_SIZE(inputs) != n) return 0;
  while (PyDict_Next(inputs, &pos, &key, &value)) {      /* exact str keys: the lookups below run no __eq__ */
    if (!PyUnicode_CheckExact(key)) return 0;
  }
  for (k=0; k<n; ++k) {
    value = PyDict_GetItemWithError(inputs, PyTuple_GET_ITEM(s->names, k));
    if (value == NULL) { PyErr_Clear(); return 0; }
    if (!plain_vector(value, s->sizes[k], u + s->offsets[k], 0)) return 0;
  }
  return vfdsl_first_input_failure(&s->core, u) < 0;
}

static void use_default_params(Stepper* s) {
  if (!s->p_is_default) {
    memcpy(s->core.data[P], PyArray_DATA((PyArrayObject*) s->p_default), s->core.size[P] * sizeof(double));
    s->p_is_default = 1;
  }
}

/* 1 when ``params`` is None (nothing copied: the defaults), or an exact dict of run-time param names with plain
 * values, copied over the defaults to p, that pass every check. */
static int plain_params(Stepper* s, PyObject* params, double* p) {
  Py_ssize_t pos = 0, k, n = PyTuple_GET_SIZE(s->param_names);
  PyObject *key, *value;
  if (params == NULL || params == Py_None) return 1;
  if (!PyDict_CheckExact(params)) return 0;
  memcpy(p, PyArray_DATA((PyArrayObject*) s->p_default), s->core.size[P] * sizeof(double));
  while (PyDict_Next(params, &pos, &key, &value)) {
    double* out;
    if (!PyUnicode_CheckExact(key)) return 0;
    for (k=0; k<n; ++k) {
      PyObject* name = PyTuple_GET_ITEM(s->param_names, k);
      if (name == key || PyUnicode_Compare(name, key) == 0) break;
    }
    if (k == n) return 0;
    out = p + s->param_offsets[k];
    if (s->param_sizes[k] == 1 && !PyList_CheckExact(value) && !PyTuple_CheckExact(value)
        && !PyArray_CheckExact(value)) {
      if (!plain_number(value, out)) return 0;
    } else if (!plain_vector(value, s->param_sizes[k], out, s->param_points[k])) {
      return 0;
    }
  }
  return vfdsl_first_failure(&s->core, p) < 0;
}

static int plain_dt(Stepper* s, PyObject* dt, double* out) {
  if (dt == Py_None || dt == NULL) *out = s->dt_default;
  else if (!plain_number(dt, out)) return 0;
  return vfdsl_dt_check(&s->core, *out) == VFDSL_DT_OK;   /* not for NAN (no default period) */
}

static PyObject* step_keywords[4];   /* "q", "inputs", "params", "dt" (interned): step's parameters in order */

/* Step's arguments q, inputs, params, dt (NULL where not given) from a vectorcall's args and kwnames, given by
 * position or keyword; 0 when they are not plainly that (more than four, an unknown or repeated keyword, no q), for the
 * Python checks to explain. Only exact str keywords are compared (no user __eq__). */
static int step_arguments(PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames, PyObject** out) {
  Py_ssize_t k, n = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
  int i;
  if (nargs > 4) return 0;
  for (i=0; i<4; ++i) out[i] = i < nargs ? args[i] : NULL;
  for (k=0; k<n; ++k) {
    PyObject* key = PyTuple_GET_ITEM(kwnames, k);
    for (i=0; i<4 && key != step_keywords[i]; ++i) ;
    if (i == 4 && PyUnicode_CheckExact(key))
      for (i=0; i<4 && PyUnicode_Compare(key, step_keywords[i]) != 0; ++i) ;
    if (i == 4 || out[i]) return 0;
    out[i] = args[nargs + k];
  }
  return out[0] != NULL;
}

#endif
