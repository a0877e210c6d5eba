/* vfdsl: a procedure's tick before its solve, in plain C: shared by the Python extension (stepper.c) and the
 * library `vfdsl export` writes, as checked_step.h is. The C of vfdsl/runtime/procedure.py's Procedure.tick
 * (whose docstring holds the semantics), step for step:
 *
 *   1. at the first tick (and the first after vfdsl_procedure_reset), every phase's captures take their value;
 *   2. raw = <prefix>_monitor_values(q, u, p) with p = [params; captured values], and the machine advances
 *      (phase_machine.h; its least-violation monitor reads the previous tick's status, 0 at the first);
 *   3. on a transition, the new phase's captures are taken from this tick's q and u, then its funnelled
 *      constraints' entry errors e_j (<prefix>_captures' outputs after the phases' captures; a non-finite or
 *      negative e is 0), every other phase's e 0;
 *   4. activity (the step's phase buffer) = the machine's weights, then 1 for the current phase's hard rows
 *      and 0 for every other's, then the funnel widths e_j x the machine's funnel factor: the one place in C
 *      where it is computed. The widths' count is the buffer's length (from the compiled step) less 2 per phase,
 *      and each phase's is the length of its entry errors' output (from the compiled captures).
 *
 * Include it after the task's generated header (which defines VFDSL_PROCEDURE, the phase buffers' slots and
 * the machine's constant arrays vfdsl_pt_*) and checked_step.h. vfdsl_procedure_open allocates every array;
 * nothing else here allocates, locks or makes a system call.
 */
#ifndef VFDSL_PROCEDURE_TICK_H
#define VFDSL_PROCEDURE_TICK_H
#include "phase_machine.h"

#define VFDSL_MONITOR_VALUES VFDSL_CAT(VFDSL_PREFIX, _monitor_values)
#define VFDSL_MONITOR_VALUES_WORK VFDSL_CAT(VFDSL_PREFIX, _monitor_values_work)
#define VFDSL_CAPTURES VFDSL_CAT(VFDSL_PREFIX, _captures)
#define VFDSL_CAPTURES_WORK VFDSL_CAT(VFDSL_PREFIX, _captures_work)
#define VFDSL_CAPTURES_SPARSITY_OUT VFDSL_CAT(VFDSL_PREFIX, _captures_sparsity_out)
#define VFDSL_N_PHASES VFDSL_PT_FINAL
#define VFDSL_N_WIDTHS (VFDSL_ACTIVITY_LENGTH - 2 * VFDSL_N_PHASES)

typedef struct {
  vfdsl_pm_table table;            /* the generated header's constant arrays */
  vfdsl_pm_state state;
  double* raw;                     /* [VFDSL_PT_RAW_SIZE]: this tick's compiled monitor values */
  double* captured;                /* the captured values, kept between ticks (p's slots after the params) */
  double* values;                  /* one phase's captures (or entry errors) as the generated function gives them */
  double* entry_error;             /* [VFDSL_N_WIDTHS]: per funnelled constraint its error at its phase's entry */
  double time;                     /* s since the first tick: the sum of dt */
  int source;                      /* the phase before the last tick */
  const casadi_real** arg;         /* work arrays of monitor_values and captures (shared) */
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
} vfdsl_procedure;

static void vfdsl_procedure_reset(vfdsl_procedure* r, double* activity);

/* Allocate the procedure's arrays and set it to its initial phase (activity: the step's phase buffer, written):
 * 0, or VFDSL_NO_MEMORY. Call vfdsl_procedure_close in every case. */
static int vfdsl_procedure_open(vfdsl_procedure* r, double* activity) {
  casadi_int values[4], captures[4];
  vfdsl_pm_table* T = &r->table;
  long n_captured = 0, most = 0;
  int k;
  T->n_phases = VFDSL_N_PHASES; T->initial = vfdsl_pt_initial[0]; T->final = vfdsl_pt_final;
  T->n_monitors = VFDSL_PT_KIND; T->kind = vfdsl_pt_kind; T->a = vfdsl_pt_a; T->b = vfdsl_pt_b; T->op = vfdsl_pt_op;
  T->threshold = vfdsl_pt_threshold; T->hold = vfdsl_pt_hold;
  T->n_watched = VFDSL_PT_WATCH_START; T->watch_start = vfdsl_pt_watch_start; T->watch_size = vfdsl_pt_watch_size;
  T->watch_offset = vfdsl_pt_watch_offset;
  T->n_transitions = VFDSL_PT_SOURCE; T->source = vfdsl_pt_source; T->target = vfdsl_pt_target;
  T->guard_start = vfdsl_pt_guard_start; T->guard_size = vfdsl_pt_guard_size; T->blend = vfdsl_pt_blend;
  T->code = vfdsl_pt_code;
  for (k=0; k<VFDSL_PT_CAPTURE_SIZE; ++k) n_captured += vfdsl_pt_capture_size[k];
  for (k=0; k<VFDSL_N_PHASES; ++k) {
    long i, n = 0;
    for (i=0; i<VFDSL_PT_CAPTURE_SIZE; ++i) if (vfdsl_pt_capture_phase[i] == k) n += vfdsl_pt_capture_size[i];
    if (n > most) most = n;
    n = VFDSL_CAPTURES_SPARSITY_OUT(VFDSL_N_PHASES + k)[0];      /* a dense column: its rows */
    if (n > most) most = n;
  }
  VFDSL_MONITOR_VALUES_WORK(&values[0], &values[1], &values[2], &values[3]);
  VFDSL_CAPTURES_WORK(&captures[0], &captures[1], &captures[2], &captures[3]);
  if (!vfdsl_work_open(values, captures, &r->arg, &r->res, &r->iw, &r->w)) return VFDSL_NO_MEMORY;
  r->raw = (double*) calloc(vfdsl_pt_raw_size[0] + 1, sizeof(double));
  r->captured = (double*) calloc(n_captured + 1, sizeof(double));
  r->values = (double*) calloc(most + 1, sizeof(double));
  r->entry_error = (double*) calloc(VFDSL_N_WIDTHS + 1, sizeof(double));
  r->state.latch = (int*) calloc(T->n_monitors + 1, sizeof(int));
  r->state.value = (int*) calloc(T->n_monitors + 1, sizeof(int));
  r->state.held = (double*) calloc(T->n_monitors + 1, sizeof(double));
  r->state.last = (double*) calloc(vfdsl_pt_u_size[0] + 1, sizeof(double));
  r->state.unchanged = (double*) calloc(T->n_watched + 1, sizeof(double));
  r->state.start = (double*) calloc(T->n_phases + 1, sizeof(double));
  r->state.weight = (double*) calloc(T->n_phases + 1, sizeof(double));
  if (!r->raw || !r->captured || !r->values || !r->entry_error || !r->state.latch
      || !r->state.value || !r->state.held || !r->state.last || !r->state.unchanged || !r->state.start
      || !r->state.weight) return VFDSL_NO_MEMORY;
  vfdsl_procedure_reset(r, activity);
  return VFDSL_OPENED;
}

static void vfdsl_procedure_close(vfdsl_procedure* r) {
  free(r->arg); free(r->res); free(r->iw); free(r->w); free(r->raw); free(r->captured); free(r->values);
  free(r->entry_error);
  free(r->state.latch); free(r->state.value); free(r->state.held); free(r->state.last); free(r->state.unchanged);
  free(r->state.start); free(r->state.weight);
  memset(r, 0, sizeof(*r));
}

/* The step's phase buffer from the machine's state: per phase its weight, then per phase 1 where its hard rows
 * are on (the current phase's), then per funnelled constraint its width, its entry error x the funnel factor. */
static void vfdsl_procedure_activity(const vfdsl_procedure* r, double* activity) {
  int k;
  for (k=0; k<VFDSL_N_PHASES; ++k) {
    activity[k] = r->state.weight[k];
    activity[VFDSL_N_PHASES + k] = k == r->state.phase ? 1.0 : 0.0;
  }
  for (k=0; k<VFDSL_N_WIDTHS; ++k) activity[2 * VFDSL_N_PHASES + k] = r->entry_error[k] * r->state.funnel;
}

/* The activity of phase k's case with nothing blended or funnelled: weight 1 and hard rows on for k alone. */
static void vfdsl_procedure_case(double* activity, int k) {
  int j;
  for (j=0; j<VFDSL_ACTIVITY_LENGTH; ++j) activity[j] = 0.0;
  activity[k] = activity[VFDSL_N_PHASES + k] = 1.0;
}

/* Back to the initial phase; its captures are retaken at the next tick. */
static void vfdsl_procedure_reset(vfdsl_procedure* r, double* activity) {
  int k;
  vfdsl_pm_init(&r->table, &r->state);
  for (k=0; k<VFDSL_N_WIDTHS; ++k) r->entry_error[k] = 0.0;
  r->time = 0.0;
  r->source = r->state.phase;
  vfdsl_procedure_activity(r, activity);
}

/* The priming of a procedure's step (vfdsl.runtime.native.LockedRunner.prime, in its order): each case of the step
 * (vfdsl.compiler.cases: each phase steady, then phase 0 at half weight, a blend) evaluated with the least-violation
 * phase forced, then without, on the core's q, u and p, so that every case's solvers have their workspace before
 * the first tick; then the machine back to its initial phase. 0, or the generated step's return code. */
static int vfdsl_procedure_prime(vfdsl_procedure* r, vfdsl_core* c, double dt, double* activity) {
  int k, flag = 0;
  for (k=0; k<=VFDSL_N_PHASES && !flag; ++k) {
    vfdsl_procedure_case(activity, k < VFDSL_N_PHASES ? k : 0);
    if (k == VFDSL_N_PHASES) activity[0] = 0.5;
    flag = vfdsl_core_eval(c, dt, 1.0);
    if (!flag) flag = vfdsl_core_eval(c, dt, 0.0);
  }
  vfdsl_procedure_reset(r, activity);
  return flag;
}

/* Output `output` of <prefix>_captures at the arguments in r->arg (q, u, then p) into r->values. */
static void vfdsl_procedure_captures(vfdsl_procedure* r, int output) {
  int k;
  for (k=0; k<2 * VFDSL_N_PHASES; ++k) r->res[k] = k == output ? r->values : 0;
  VFDSL_CAPTURES(r->arg, r->res, r->iw, r->w, 0);
}

/* The phase's captures from the arguments in r->arg (q, u, then p), written into p's slots and kept. */
static void vfdsl_procedure_capture(vfdsl_procedure* r, int phase, double* p) {
  int k, i, j = 0;
  long kept = 0;
  vfdsl_procedure_captures(r, phase);
  for (k=0; k<VFDSL_PT_CAPTURE_SIZE; ++k) {
    if (vfdsl_pt_capture_phase[k] == phase)
      for (i=0; i<vfdsl_pt_capture_size[k]; ++i, ++j)
        p[vfdsl_pt_capture_offset[k] + i] = r->captured[kept + i] = r->values[j];
    kept += vfdsl_pt_capture_size[k];
  }
}

/* The entered phase's funnelled constraints' entry errors (its captures taken), 0 for every other phase's and
 * where not a finite number > 0. */
static void vfdsl_procedure_measure_entry(vfdsl_procedure* r, int phase) {
  int k, i, j = 0;
  vfdsl_procedure_captures(r, VFDSL_N_PHASES + phase);
  for (k=0; k<VFDSL_N_PHASES; ++k) {
    int n = (int) VFDSL_CAPTURES_SPARSITY_OUT(VFDSL_N_PHASES + k)[0];
    for (i=0; i<n; ++i, ++j) {
      double e = r->values[i];
      r->entry_error[j] = k == phase && isfinite(e) && e > 0 ? e : 0.0;
    }
  }
}

/* The machine's tick before the solve, on the checked q, u and params p (p's capture slots are overwritten with
 * the captured values), dt and the previous solve's status: writes activity, returns -1 or the transition fired. */
static int vfdsl_procedure_tick(vfdsl_procedure* r, const double* q, const double* u, double* p, double dt,
                                int last_status, double* activity) {
  int k, i, first = !r->state.started;
  long kept = 0;
  for (k=0; k<VFDSL_PT_CAPTURE_SIZE; ++k)
    for (i=0; i<vfdsl_pt_capture_size[k]; ++i) p[vfdsl_pt_capture_offset[k] + i] = r->captured[kept++];
  r->arg[0] = q; r->arg[1] = u; r->arg[2] = p;
  if (first)
    for (k=0; k<VFDSL_N_PHASES; ++k) vfdsl_procedure_capture(r, k, p);
  r->res[0] = r->raw;
  VFDSL_MONITOR_VALUES(r->arg, r->res, r->iw, r->w, 0);
  r->source = r->state.phase;
  vfdsl_pm_advance(&r->table, &r->state, r->raw, u, dt, first ? 0 : last_status);
  r->time += dt;
  if (r->state.fired >= 0) {
    vfdsl_procedure_capture(r, r->state.phase, p);
    vfdsl_procedure_measure_entry(r, r->state.phase);
  }
  vfdsl_procedure_activity(r, activity);
  return r->state.fired;
}

#endif
