/* @API@: the C API of the virtual fixture "@TASK@" (see @API@.h), written by `vfdsl export`.
 *
 * A controller is one vfdsl_core (checked_step.h: the checks and the evaluation of a tick, the same
 * code as Python's Controller.step) over buffers inside the controller, plus a busy flag: every call on a
 * controller (the readers _violations, _error_index and _error_check included) sets it for its duration,
 * and a call that finds it set returns VF_ERR_BUSY without touching anything (an atomic exchange, not a
 * lock: no call ever waits). A procedure's controller also holds its machine (procedure_tick.h, the same code as
 * Python's native Controller), run before each tick's solve; a teleoperated task's its readout (teleop_readout.h),
 * evaluated after each tick's solve.
 */
#include "@TICK@.h"
#define VFDSL_PREFIX @TICK@
#include "checked_step.h"
#ifdef VFDSL_PROCEDURE
#include "procedure_tick.h"
#endif
#ifdef VFDSL_TELEOP
#include "teleop_readout.h"
#endif
#include "@API@.h"

#if defined(__GNUC__) || defined(__clang__)
#define VF_EXPORT __attribute__((visibility("default")))
#else
#define VF_EXPORT
#endif

/* ------------------------------------------------------------------------------------ the task */
@TABLES@
/* ------------------------------------------------------------------------------ the controller */

/* One array per buffer of the step (VFDSL_BUFFERS in the generated header): double q[...], u[...], ... */
#define VF_BUFFER(slot, name, length) double name[(length) + 1];

struct @API@ {
  vfdsl_core core;
  VFDSL_BUFFERS(VF_BUFFER)                                        /* the step's arguments, then its results */
  double candidate[NP + 1];                                       /* params being checked */
  int busy;
  int error_index, error_check;
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure procedure;                                      /* the phase machine, captures, activity */
  double activity[VFDSL_ACTIVITY_LENGTH + 1];                     /* the step's phase buffer */
#endif
#ifdef VFDSL_TELEOP
  vfdsl_teleop teleop;                                            /* the haptic readout and its state */
#endif
};
#undef VF_BUFFER

/* The flag is the only field a reader (a const controller) writes: controllers are never const objects. */
static int enter(const @API@* c) {
  return !__atomic_exchange_n(&((@API@*) c)->busy, 1, __ATOMIC_ACQUIRE);
}

static void leave(const @API@* c) {
  __atomic_store_n(&((@API@*) c)->busy, 0, __ATOMIC_RELEASE);
}

static int refuse(@API@* c, int code, long index, long check) {
  c->error_index = (int) index;
  c->error_check = (int) check;
  return code;
}

VF_EXPORT @API@* @API@_new(void) {
  @API@* c = (@API@*) calloc(1, sizeof(@API@));
  double dt = DEFAULT_PERIOD > 0 ? DEFAULT_PERIOD : 0.01;
  if (!c) return 0;
#define VF_BIND(slot, name, length) c->core.data[slot] = c->name; c->core.size[slot] = length;
  VFDSL_BUFFERS(VF_BIND)
#undef VF_BIND
  c->core.q_lower = q_lower;
  c->core.q_upper = q_upper;
  c->core.dt_min = MIN_PERIOD;
  c->core.dt_max = MAX_PERIOD;
  c->core.strict = strict;
  c->core.n_margins = NCHECKS;
  c->error_index = c->error_check = -1;
  memcpy(c->p, p_default, sizeof(double) * NP);
#ifdef VFDSL_PROCEDURE
  c->core.activity = c->activity;
#endif
  if (vfdsl_core_open(&c->core) != VFDSL_OPENED) {
    @API@_free(c);
    return 0;
  }
#ifdef VFDSL_PROCEDURE
  if (vfdsl_procedure_open(&c->procedure, c->activity) != VFDSL_OPENED) {
    @API@_free(c);
    return 0;
  }
#endif
#ifdef VFDSL_TELEOP
  if (vfdsl_teleop_open(&c->teleop) != VFDSL_OPENED) {
    @API@_free(c);
    return 0;
  }
#endif
  /* Priming, as Python's Controller: every solver's workspace is allocated now (recovery forced once; a
     procedure's, in each case of its step: procedure_tick.h). */
  memcpy(c->q, start, sizeof(double) * NQ);
#ifdef VFDSL_PROCEDURE
  if (vfdsl_procedure_prime(&c->procedure, &c->core, dt, c->activity)) {
#else
  if (vfdsl_core_eval(&c->core, dt, 1.0) || vfdsl_core_eval(&c->core, dt, 0.0)) {
#endif
    @API@_free(c);
    return 0;
  }
  return c;
}

VF_EXPORT void @API@_free(@API@* c) {
  if (!c) return;
  vfdsl_core_close(&c->core);
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure_close(&c->procedure);
#endif
#ifdef VFDSL_TELEOP
  vfdsl_teleop_close(&c->teleop);
#endif
  free(c);
}

/* The checks of Controller.step, in its order (q, inputs, dt), then the tick. */
static int tick(@API@* c, const double* q, const double* inputs, double dt) {
  long i = vfdsl_first_nonfinite(q, NQ);
  if (i >= 0) return refuse(c, VF_ERR_Q_NONFINITE, i, -1);
  i = vfdsl_q_outside(&c->core, q);
  if (i >= 0) return refuse(c, VF_ERR_Q_RANGE, i, -1);
  i = vfdsl_first_input_failure(&c->core, inputs);
  if (i >= 0) return refuse(c, VF_ERR_INPUT, i, -1);
  switch (vfdsl_dt_check(&c->core, dt)) {
    case VFDSL_DT_NOT_POSITIVE: return refuse(c, VF_ERR_DT, -1, -1);
    case VFDSL_DT_FAR: return refuse(c, VF_ERR_DT_PERIOD, -1, -1);
  }
  memcpy(c->q, q, sizeof(double) * NQ);
  memcpy(c->u, inputs, sizeof(double) * NU);
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure_tick(&c->procedure, c->q, c->u, c->p, dt, (int) c->status[0], c->activity);
#endif
  if (vfdsl_core_eval(&c->core, dt, 0.0)) return refuse(c, VF_ERR_SOLVER, -1, -1);
#ifdef VFDSL_TELEOP
#ifdef VFDSL_PROCEDURE
  if (vfdsl_teleop_eval(&c->teleop, &c->core, c->activity)) return refuse(c, VF_ERR_SOLVER, -1, -1);
#else
  if (vfdsl_teleop_eval(&c->teleop, &c->core, 0)) return refuse(c, VF_ERR_SOLVER, -1, -1);
#endif
#endif
  c->error_index = c->error_check = -1;
  return (int) c->status[0];
}

VF_EXPORT int @API@_step(@API@* c, const double q[@MACRO@_NUM_JOINTS], @INPUTS_ARGUMENT@, double dt,
                         double dq_out[@MACRO@_NUM_JOINTS]) {
  int code;
  if (!c) {
    code = VF_ERR_NULL;
  } else if (!enter(c)) {
    code = VF_ERR_BUSY;
  } else {
    code = !q || !dq_out || (!inputs && NU > 0) ? refuse(c, VF_ERR_NULL, -1, -1) : tick(c, q, inputs, dt);
    if (code >= 0) memcpy(dq_out, c->x, sizeof(double) * NQ);
    leave(c);
  }
  if (code < 0 && dq_out) memset(dq_out, 0, sizeof(double) * NQ);
  return code;
}

/* The run-time param holding number `at` of the params' vector. */
static int param_of(long at) {
  int k = 0;
  while (k + 1 < NPARAMS && at >= param_offsets[k + 1]) ++k;
  return k;
}

/* candidate = the current params with [offset, offset + n) replaced by values; kept if every check holds. */
static int set_values(@API@* c, long offset, long n, const double* values) {
  long i;
  memcpy(c->candidate, c->p, sizeof(double) * NP);
  memcpy(c->candidate + offset, values, sizeof(double) * n);
  i = vfdsl_first_nonfinite(values, n);
  if (i >= 0) return refuse(c, VF_ERR_PARAM, param_of(offset + i), -1);
  i = vfdsl_first_failure(&c->core, c->candidate);
  if (i >= 0) return refuse(c, VF_ERR_PARAM, check_params[i], i);
  memcpy(c->p, c->candidate, sizeof(double) * NP);
  c->error_index = c->error_check = -1;
  return 0;
}

VF_EXPORT int @API@_set_param(@API@* c, int index, const double* values) {
  int code;
  if (!c) return VF_ERR_NULL;
  if (!enter(c)) return VF_ERR_BUSY;
  if (!values) code = refuse(c, VF_ERR_NULL, -1, -1);
  else if (index < 0 || index >= NPARAMS) code = refuse(c, VF_ERR_PARAM_INDEX, index, -1);
  else code = set_values(c, param_offsets[index], param_sizes[index], values);
  leave(c);
  return code;
}

VF_EXPORT int @API@_set_params(@API@* c, @PARAMS_ARGUMENT@) {
  int code;
  if (!c) return VF_ERR_NULL;
  if (!enter(c)) return VF_ERR_BUSY;
  /* the run-time params' numbers only: the captured values after them are the procedure's (setting them does
     nothing, and a NaN there is no param's error) */
  code = !values && NP_SET > 0 ? refuse(c, VF_ERR_NULL, -1, -1) : set_values(c, 0, NP_SET, values);
  leave(c);
  return code;
}

static int last_error(const @API@* c, int check) {
  int value;
  if (!c) return -1;
  if (!enter(c)) return VF_ERR_BUSY;
  value = check ? c->error_check : c->error_index;
  leave(c);
  return value;
}

VF_EXPORT int @API@_error_index(const @API@* c) { return last_error(c, 0); }
VF_EXPORT int @API@_error_check(const @API@* c) { return last_error(c, 1); }
VF_EXPORT const char* @API@_check_meaning(int k) {
  if (k >= 0 && k < NCHECKS) return check_meanings[k];
  return k == -1 ? "no check of the task failed (the value was NaN or inf, or the error was not VF_ERR_PARAM)"
                 : "not a check of this task";
}

VF_EXPORT int @API@_violations(const @API@* c, @API@_violation* out, int capacity) {
  int i, n = 0;
  if (!c) return VF_ERR_NULL;
  if (!enter(c)) return VF_ERR_BUSY;
  for (i=0; i<NROWS; ++i) {
    if (rows[i].soft || !(c->violation[i] > 0)) continue;
    if (out && n < capacity) {
      @API@_violation v = {rows[i].label, rows[i].primitive, rows[i].file, rows[i].line, rows[i].unit,
                           c->violation[i]};
      out[n] = v;
    }
    ++n;
  }
  for (i=0; i<NSLACK; ++i) {
    if (!(c->x[NQ + i] > FEASIBILITY_TOLERANCE)) continue;
    if (out && n < capacity) {
      @API@_violation v = {slacks[i].label, slacks[i].primitive, slacks[i].file, slacks[i].line, slacks[i].unit,
                           c->x[NQ + i]};
      out[n] = v;
    }
    ++n;
  }
  leave(c);
  return n;
}

VF_EXPORT const char* @API@_error_message(int code) {
  switch (code) {
    case VF_ERR_NULL: return "a pointer argument is NULL";
    case VF_ERR_Q_NONFINITE: return "q (joint coordinates) contains NaN or inf";
    case VF_ERR_Q_RANGE: return "q is far outside its joint's limits: check the unit (radians, metres), the joint "
                                "order, or the encoder";
    case VF_ERR_INPUT: return INPUT_RULE;
    case VF_ERR_DT: return "dt must be a positive number of seconds";
    case VF_ERR_DT_PERIOD: return "dt " DT_RULE " (dt is in seconds: 1 ms is 0.001)";
    case VF_ERR_PARAM_INDEX: return "no run-time param has this index";
    case VF_ERR_PARAM: return "a param value is NaN or inf, or fails a check (see _error_check, _check_meaning)";
    case VF_ERR_BUSY: return "another thread is inside a call on this controller: nothing was done";
    case VF_ERR_SOLVER: return "the generated step failed";
    case VF_ERR_NO_TELEOP: return "the task has no teleop term: there is no haptic readout";
    default: return code >= 0 ? "no error (status bits)" : "unknown error code";
  }
}

VF_EXPORT int @API@_num_joints(void) { return NQ; }
VF_EXPORT const char* @API@_joint_name(int i) { return i >= 0 && i < NQ ? joint_names[i] : ""; }
VF_EXPORT const char* @API@_joint_unit(int i) { return i >= 0 && i < NQ ? joint_units[i] : ""; }
VF_EXPORT double @API@_default_period(void) { return DEFAULT_PERIOD; }
VF_EXPORT double @API@_min_period(void) { return MIN_PERIOD; }
VF_EXPORT double @API@_max_period(void) { return MAX_PERIOD; }
VF_EXPORT const double* @API@_start(void) { return start; }
VF_EXPORT int @API@_input_length(void) { return NU; }
VF_EXPORT int @API@_num_inputs(void) { return NINPUTS; }
VF_EXPORT const char* @API@_input_name(int k) { return k >= 0 && k < NINPUTS ? input_names[k] : ""; }
VF_EXPORT int @API@_input_size(int k) { return k >= 0 && k < NINPUTS ? input_sizes[k] : 0; }
VF_EXPORT const char* @API@_input_unit(int k) { return k >= 0 && k < NINPUTS ? input_units[k] : ""; }
VF_EXPORT int @API@_param_length(void) { return NP; }
VF_EXPORT int @API@_num_params(void) { return NPARAMS; }
VF_EXPORT const char* @API@_param_name(int k) { return k >= 0 && k < NPARAMS ? param_names[k] : ""; }
VF_EXPORT const char* @API@_param_type(int k) { return k >= 0 && k < NPARAMS ? param_types[k] : ""; }
VF_EXPORT int @API@_param_size(int k) { return k >= 0 && k < NPARAMS ? param_sizes[k] : 0; }
VF_EXPORT const char* @API@_param_unit(int k) { return k >= 0 && k < NPARAMS ? param_units[k] : ""; }
VF_EXPORT const double* @API@_param_default(int k) {
  return k >= 0 && k < NPARAMS ? p_default + param_offsets[k] : 0;
}
VF_EXPORT int @API@_num_rows(void) { return NROWS; }

/* What the procedure holds after the last tick (-1 without phases): its phase (what 0), the transition fired
 * (what 1, -1: none), named monitor i (what 2: 1 when it held, else 0). */
static int machine(const @API@* c, int what, int i) {
  int value = -1;
  if (!c) return VF_ERR_NULL;
  if (!enter(c)) return VF_ERR_BUSY;
#ifdef VFDSL_PROCEDURE
  if (what == 0) value = c->procedure.state.phase;
  else if (what == 1) value = c->procedure.state.fired;
  else if (i >= 0 && i < NMONITORS) value = c->procedure.state.value[monitor_index[i]] == VFDSL_PM_TRUE;
#else
  (void) what; (void) i;
#endif
  leave(c);
  return value;
}

VF_EXPORT int @API@_phase(const @API@* c) { return machine(c, 0, 0); }
VF_EXPORT int @API@_transition(const @API@* c) { return machine(c, 1, 0); }
VF_EXPORT int @API@_monitor(const @API@* c, int i) { return machine(c, 2, i); }

VF_EXPORT int @API@_reset(@API@* c) {
  if (!c) return VF_ERR_NULL;
  if (!enter(c)) return VF_ERR_BUSY;
#ifdef VFDSL_PROCEDURE
  vfdsl_procedure_reset(&c->procedure, c->activity);
#endif
#ifdef VFDSL_TELEOP
  vfdsl_teleop_reset(&c->teleop);
#endif
  leave(c);
  return 0;
}

VF_EXPORT int @API@_teleop(const @API@* c, @API@_teleop_readout* out) {
  if (!c || !out) return VF_ERR_NULL;
#ifdef VFDSL_TELEOP
  if (!enter(c)) return VF_ERR_BUSY;
  memcpy(out->force, c->teleop.force, sizeof out->force);
  memcpy(out->setpoint, c->teleop.setpoint, sizeof out->setpoint);
  memcpy(out->goal, c->teleop.goal, sizeof out->goal);
  memcpy(out->depth, c->teleop.depth, sizeof out->depth);
  out->following = c->teleop.following[0] > 0.5;
  leave(c);
  return 0;
#else
  return VF_ERR_NO_TELEOP;
#endif
}

VF_EXPORT int @API@_row_acting(const @API@* c, int i) {
  int value = 0;
  if (!c) return VF_ERR_NULL;
#ifdef VFDSL_TELEOP
  if (!enter(c)) return VF_ERR_BUSY;
  value = i >= 0 && i < NROWS && c->teleop.acting[i] > 0.5;
  leave(c);
#else
  (void) i;
#endif
  return value;
}

VF_EXPORT int @API@_is_teleoperated(void) {
#ifdef VFDSL_TELEOP
  return 1;
#else
  return 0;
#endif
}

VF_EXPORT int @API@_num_phases(void) { return NPHASES; }
VF_EXPORT const char* @API@_phase_name(int i) { return i >= 0 && i < NPHASES ? phase_names[i] : ""; }
VF_EXPORT int @API@_num_monitors(void) { return NMONITORS; }
VF_EXPORT const char* @API@_monitor_name(int i) { return i >= 0 && i < NMONITORS ? monitor_names[i] : ""; }
VF_EXPORT int @API@_num_transitions(void) { return NTRANSITIONS; }
VF_EXPORT const char* @API@_transition_guard(int k) {
  return k >= 0 && k < NTRANSITIONS ? transition_guards[k] : "";
}
VF_EXPORT int @API@_transition_source(int k) { return k >= 0 && k < NTRANSITIONS ? transition_sources[k] : -1; }
VF_EXPORT int @API@_transition_target(int k) { return k >= 0 && k < NTRANSITIONS ? transition_targets[k] : -1; }
VF_EXPORT const char* @API@_row_label(int i) { return i >= 0 && i < NROWS ? rows[i].label : ""; }
