/* vfdsl: the checked tick of one task in plain C, shared by the Python extension (stepper.c) and the
 * library `vfdsl export` writes, so that both accept exactly the same values with the same code.
 *
 * Include it after the task's generated header, with VFDSL_PREFIX defined as the generated symbol.
 *
 * A vfdsl_core is one controller's evaluation of the generated step: its memory slot, its work arrays
 * and the buffers the step reads and writes, which the caller owns (their slots VFDSL_Q, ... and
 * VFDSL_BUFFERS are declared in the generated header, from vfdsl/codegen/tick_buffers.py). Its checks,
 * made before anything is evaluated:
 *
 *   q       every entry finite and within [q_lower_i, q_upper_i] (the joint limits widened by the
 *           joint's span on each side: further out is a unit mistake or a faulty encoder);
 *   dt      positive and finite (else VFDSL_DT_NOT_POSITIVE), and within [dt_min, dt_max], the task's range around
 *           its period computed at compile time (vfdsl.runtime.values.dt_range; else VFDSL_DT_FAR: a unit slip);
 *   params  the task's column of checks, evaluated by the generated <prefix>_admissible: check i holds
 *           iff margin i is finite and >= 0 (> 0 where strict[i]);
 *   inputs  every number finite, then the column of their types' checks, evaluated by the generated
 *           <prefix>_input_checks: margin m (check m / nu of u[m % nu]) holds iff it is finite and >= 0
 *           (vfdsl.inputs: a type's plausibility checks; any finite size passes FINITE: beyond the speed
 *           bounds they saturate).
 *
 * vfdsl_core_open allocates everything the core needs (work arrays, a memory slot); nothing else here
 * allocates, locks or makes a system call.
 */
#ifndef VFDSL_CHECKED_STEP_H
#define VFDSL_CHECKED_STEP_H
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define VFDSL_CAT_(a, b) a##b
#define VFDSL_CAT(a, b) VFDSL_CAT_(a, b)
#define VFDSL_STEP VFDSL_PREFIX
#define VFDSL_STEP_CHECKOUT VFDSL_CAT(VFDSL_PREFIX, _checkout)
#define VFDSL_STEP_RELEASE VFDSL_CAT(VFDSL_PREFIX, _release)
#define VFDSL_STEP_WORK VFDSL_CAT(VFDSL_PREFIX, _work)
#define VFDSL_ADMISSIBLE VFDSL_CAT(VFDSL_PREFIX, _admissible)
#define VFDSL_ADMISSIBLE_WORK VFDSL_CAT(VFDSL_PREFIX, _admissible_work)
#define VFDSL_INPUT_CHECKS VFDSL_CAT(VFDSL_PREFIX, _input_checks)
#define VFDSL_INPUT_CHECKS_WORK VFDSL_CAT(VFDSL_PREFIX, _input_checks_work)
#define VFDSL_INPUT_CHECKS_SPARSITY VFDSL_CAT(VFDSL_PREFIX, _input_checks_sparsity_out)

enum { VFDSL_OPENED = 0, VFDSL_NO_MEMORY = 1, VFDSL_NO_SLOT = 2 };

typedef struct {
  double* data[VFDSL_N_BUFFERS];   /* set by the caller before vfdsl_core_open */
  long size[VFDSL_N_BUFFERS];
#ifdef VFDSL_PROCEDURE
  double* activity;                /* a procedure's phase buffer (VFDSL_ACTIVITY_LENGTH), set before vfdsl_core_open */
#endif
  const double* q_lower;           /* nq admissible bounds each */
  const double* q_upper;
  double dt_min, dt_max;            /* the admissible dt, s */
  const unsigned char* strict;     /* n_margins flags: 1 where a margin must be > 0 */
  long n_margins;
  double* margins;                 /* the column of the last evaluated params */
  long n_input_margins;            /* set by vfdsl_core_open: the length of the inputs' column of checks */
  double* input_margins;           /* the column of the last checked inputs */
  const casadi_real** check_arg;
  casadi_real** check_res;
  casadi_int* check_iw;
  casadi_real* check_w;
  const casadi_real** arg;
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
  int slot;                        /* memory slot of the generated code, -1 when none */
} vfdsl_core;

/* Work arrays arg, res, iw, w shared by two generated functions, a and b their sizes as their _work functions give
 * them ({sz_arg, sz_res, sz_iw, sz_w}): 1, or 0 when one could not be allocated. */
static int vfdsl_work_open(const casadi_int* a, const casadi_int* b, const casadi_real*** arg, casadi_real*** res,
                           casadi_int** iw, casadi_real** w) {
  casadi_int n[4];
  int k;
  for (k=0; k<4; ++k) n[k] = a[k] > b[k] ? a[k] : b[k];
  *arg = (const casadi_real**) calloc(n[0] + 1, sizeof(casadi_real*));
  *res = (casadi_real**) calloc(n[1] + 1, sizeof(casadi_real*));
  *iw = (casadi_int*) calloc(n[2] + 1, sizeof(casadi_int));
  *w = (casadi_real*) calloc(n[3] + 1, sizeof(casadi_real));
  return *arg && *res && *iw && *w;
}

/* Allocate the work arrays and check out a memory slot: VFDSL_OPENED, VFDSL_NO_MEMORY or VFDSL_NO_SLOT
 * (all VFDSL_MAX_SLOTS controllers of the task exist). Call vfdsl_core_close in every case. */
static int vfdsl_core_open(vfdsl_core* c) {
  casadi_int checks[4], inputs[4], step[4];
  int k, worked;
  c->slot = -1;
  c->n_input_margins = (long) VFDSL_INPUT_CHECKS_SPARSITY(0)[0];    /* a dense column: its number of rows */
  VFDSL_ADMISSIBLE_WORK(&checks[0], &checks[1], &checks[2], &checks[3]);
  VFDSL_INPUT_CHECKS_WORK(&inputs[0], &inputs[1], &inputs[2], &inputs[3]);     /* both checks share the work arrays */
  VFDSL_STEP_WORK(&step[0], &step[1], &step[2], &step[3]);
  worked = vfdsl_work_open(checks, inputs, &c->check_arg, &c->check_res, &c->check_iw, &c->check_w);
  worked = vfdsl_work_open(step, step, &c->arg, &c->res, &c->iw, &c->w) && worked;
  c->margins = (double*) calloc(c->n_margins + 1, sizeof(double));
  c->input_margins = (double*) calloc(c->n_input_margins + 1, sizeof(double));
  if (!worked || !c->margins || !c->input_margins) return VFDSL_NO_MEMORY;
#ifdef VFDSL_PROCEDURE                /* a procedure's step takes its phase buffer at VFDSL_ACTIVITY_ARG */
  for (k=0; k<VFDSL_N_ARGS; ++k) c->arg[k < VFDSL_ACTIVITY_ARG ? k : k + 1] = c->data[k];
  c->arg[VFDSL_ACTIVITY_ARG] = c->activity;
#else
  for (k=0; k<VFDSL_N_ARGS; ++k) c->arg[k] = c->data[k];
#endif
  for (k=VFDSL_N_ARGS; k<VFDSL_N_BUFFERS; ++k) c->res[k - VFDSL_N_ARGS] = c->data[k];
  c->slot = VFDSL_STEP_CHECKOUT();
  return c->slot < 0 ? VFDSL_NO_SLOT : VFDSL_OPENED;
}

static void vfdsl_core_close(vfdsl_core* c) {
  if (c->slot >= 0) VFDSL_STEP_RELEASE(c->slot);
  c->slot = -1;
  free(c->arg); free(c->res); free(c->iw); free(c->w); free(c->margins); free(c->input_margins);
  free(c->check_arg); free(c->check_res); free(c->check_iw); free(c->check_w);
  c->arg = 0; c->res = 0; c->iw = 0; c->w = 0; c->margins = 0; c->input_margins = 0;
  c->check_arg = 0; c->check_res = 0; c->check_iw = 0; c->check_w = 0;
}

/* The index of the first non-finite entry of x[0..n), or -1. */
static long vfdsl_first_nonfinite(const double* x, long n) {
  long i;
  for (i=0; i<n; ++i) if (!isfinite(x[i])) return i;
  return -1;
}

/* The index of the first joint whose coordinate q_i is non-finite or outside [q_lower_i, q_upper_i], or -1. */
static long vfdsl_q_outside(const vfdsl_core* c, const double* q) {
  long i;
  for (i=0; i<c->size[VFDSL_Q]; ++i) if (!(q[i] >= c->q_lower[i] && q[i] <= c->q_upper[i])) return i;
  return -1;
}

enum { VFDSL_DT_OK = 0, VFDSL_DT_NOT_POSITIVE = 1, VFDSL_DT_FAR = 2 };

/* VFDSL_DT_OK when dt_min <= dt <= dt_max; VFDSL_DT_NOT_POSITIVE for NaN, inf and dt <= 0; else VFDSL_DT_FAR. */
static int vfdsl_dt_check(const vfdsl_core* c, double dt) {
  if (!(dt > 0 && isfinite(dt))) return VFDSL_DT_NOT_POSITIVE;
  return dt >= c->dt_min && dt <= c->dt_max ? VFDSL_DT_OK : VFDSL_DT_FAR;
}

/* The index of the first check of the params p that fails, or -1 (evaluates the column into margins). */
static long vfdsl_first_failure(vfdsl_core* c, const double* p) {
  long i;
  c->check_arg[0] = p;
  c->check_res[0] = c->margins;
  if (VFDSL_ADMISSIBLE(c->check_arg, c->check_res, c->check_iw, c->check_w, 0)) return 0;
  for (i=0; i<c->n_margins; ++i) {
    double m = c->margins[i];
    if (!isfinite(m) || !(c->strict[i] ? m > 0 : m >= 0)) return i;
  }
  return -1;
}

/* The index in u of the first number that is non-finite or fails a check of its input's type, or -1 (evaluates
 * the inputs' column into input_margins: margin m is check m / nu of u[m % nu]). */
static long vfdsl_first_input_failure(vfdsl_core* c, const double* u) {
  long i, nu = c->size[VFDSL_U];
  i = vfdsl_first_nonfinite(u, nu);
  if (i >= 0 || c->n_input_margins == 0) return i;
  c->check_arg[0] = u;
  c->check_res[0] = c->input_margins;
  if (VFDSL_INPUT_CHECKS(c->check_arg, c->check_res, c->check_iw, c->check_w, 0)) return 0;
  for (i=0; i<c->n_input_margins; ++i) {
    double m = c->input_margins[i];
    if (!(isfinite(m) && m >= 0)) return i % nu;
  }
  return -1;
}

/* One tick on the buffers q, u, p (already checked) with dt and recover: the generated step's return code
 * (0: x, status and violation are written; VFDSL_SLOT_BUSY: another thread is inside this slot). */
static int vfdsl_core_eval(vfdsl_core* c, double dt, double recover) {
  c->data[VFDSL_DT][0] = dt;
  c->data[VFDSL_RECOVER][0] = recover;
  return VFDSL_STEP(c->arg, c->res, c->iw, c->w, c->slot);
}

#endif
