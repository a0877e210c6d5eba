/* vfdsl: a procedure's methods of the Stepper (tick, reset, machine), for stepper.c only (included there when the
 * task has phases, VFDSL_PROCEDURE): the machine of procedure_tick.h run and read under the Stepper's lock. */
#ifndef VFDSL_STEPPER_PROCEDURE_H
#define VFDSL_STEPPER_PROCEDURE_H

/* tick(q, u, p, dt): the checked step's tick, the machine included (checked float64 arrays, p None: the
 * defaults) -> dq. */
static PyObject* Stepper_tick(Stepper* s, PyObject* args) {
  PyObject *in[3], *result;
  double dt;
  if (!ready(s)) return NULL;
  if (!PyArg_ParseTuple(args, "O!O!Od", &PyArray_Type, &in[0], &PyArray_Type, &in[1], &in[2], &dt)) return NULL;
  if (load(s, in) < 0) return NULL;
  result = tick(s, dt);
  PyThread_release_lock(s->lock);
  return result;
}

/* reset(): the procedure back to its initial phase, captures retaken at the next tick. */
static PyObject* Stepper_reset(Stepper* s, PyObject* unused) {
  if (!ready(s)) return NULL;
  lock(s);
  vfdsl_procedure_reset(&s->procedure, s->activity);
  PyThread_release_lock(s->lock);
  Py_RETURN_NONE;
}

/* machine() -> (phase, source, fired, time, activity, monitor values): the procedure after its last tick (a
 * copy, taken under the lock). */
static PyObject* Stepper_machine(Stepper* s, PyObject* unused) {
  npy_intp na = VFDSL_ACTIVITY_LENGTH, nm = s->procedure.table.n_monitors, k;
  PyObject *activity, *values, *result;
  if (!ready(s)) return NULL;
  activity = PyArray_SimpleNew(1, &na, NPY_DOUBLE);
  values = PyArray_SimpleNew(1, &nm, NPY_INT);
  if (!activity || !values) { Py_XDECREF(activity); Py_XDECREF(values); return NULL; }
  lock(s);
  memcpy(PyArray_DATA((PyArrayObject*) activity), s->activity, na * sizeof(double));
  for (k=0; k<nm; ++k) ((int*) PyArray_DATA((PyArrayObject*) values))[k] = s->procedure.state.value[k];
  result = Py_BuildValue("iiidNN", s->procedure.state.phase, s->procedure.source, s->procedure.state.fired,
                         s->procedure.time, activity, values);
  PyThread_release_lock(s->lock);
  return result;
}
#endif
