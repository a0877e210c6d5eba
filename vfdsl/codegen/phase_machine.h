/* vfdsl: the discrete part of a procedure's tick: monitors, the phase and its transitions, blend weights, funnel.
 *
 * The C of vfdsl/runtime/phase_machine.py (whose docstring holds the semantics), step for step in the same order,
 * so that both give the same phases, transitions and weights to the last bit (compiled with -ffp-contract=off, as
 * vfdsl.codegen.build.FLAGS does). Static functions only, no allocation, nothing from libc but math.h: the table
 * is constant arrays (MachineTable.c_arrays() in Python), the state arrays the caller's.
 *
 *   vfdsl_pm_init(table, state)                             the state before the first tick
 *   fired = vfdsl_pm_advance(table, state, raw, u, dt, last_status)
 *                                                           one tick: -1 or the transition fired; state->phase,
 *                                                           ->weight[phase], ->funnel, ->value[monitor] updated
 */
#ifndef VFDSL_PHASE_MACHINE_H
#define VFDSL_PHASE_MACHINE_H

#include <math.h>

enum { VFDSL_PM_FALSE = 0, VFDSL_PM_TRUE = 1, VFDSL_PM_UNKNOWN = 2 };
enum { VFDSL_PM_COMPARE = 0, VFDSL_PM_ELAPSED = 1, VFDSL_PM_UNCHANGED = 2, VFDSL_PM_LEAST_VIOLATION = 3,
       VFDSL_PM_LOGIC = 4 };
enum { VFDSL_PM_GT = 0, VFDSL_PM_GE = 1, VFDSL_PM_LT = 2, VFDSL_PM_LE = 3 };
enum { VFDSL_PM_AND = -1, VFDSL_PM_OR = -2, VFDSL_PM_NOT = -3 };
enum { VFDSL_PM_MAX_STACK = 32, VFDSL_PM_LEAST_VIOLATION_BIT = 1 };

typedef struct {
  int n_phases, initial;
  const int* final;                       /* [n_phases] */
  int n_monitors;                         /* each: kind; a: raw index, watched input or program start; */
  const int *kind, *a, *b, *op;           /* b: release index (-1: none) or program length; op: time comparison */
  const double *threshold, *hold;         /* s */
  int n_watched;                          /* watched inputs: slices of u, and where their last values are kept */
  const int *watch_start, *watch_size, *watch_offset;
  int n_transitions;                      /* in file order: source (-1: any but target), target, guard program, blend (s) */
  const int *source, *target, *guard_start, *guard_size;
  const double* blend;
  const int* code;                        /* every postfix program: m >= 0 pushes monitor m, or AND, OR, NOT */
} vfdsl_pm_table;

typedef struct {
  int started, phase, fired;
  double elapsed, blend, funnel;          /* blend: the running blend's B */
  int *latch, *value;                     /* [n_monitors] */
  double* held;                           /* [n_monitors] */
  double* last;                           /* [sum of watch_size] */
  double* unchanged;                      /* [n_watched] */
  double *start, *weight;                 /* [n_phases]: weights at the last transition, and this tick's */
} vfdsl_pm_state;

static void vfdsl_pm_init(const vfdsl_pm_table* T, vfdsl_pm_state* S) {
  int i, k, n = 0;
  S->started = 0; S->phase = T->initial; S->fired = -1;
  S->elapsed = 0.0; S->blend = 0.0; S->funnel = 0.0;
  for (i=0; i<T->n_phases; ++i) S->weight[i] = S->start[i] = i == T->initial ? 1.0 : 0.0;
  for (i=0; i<T->n_monitors; ++i) { S->latch[i] = 0; S->held[i] = 0.0; S->value[i] = VFDSL_PM_FALSE; }
  for (i=0; i<T->n_watched; ++i) { S->unchanged[i] = 0.0; n += T->watch_size[i]; }
  for (k=0; k<n; ++k) S->last[k] = NAN;
}

static int vfdsl_pm_reached(double t, double T, double dt) { return t >= T - 0.5 * dt; }

static int vfdsl_pm_compare_time(double t, int op, double T, double dt) {
  double half = 0.5 * dt;
  if (op == VFDSL_PM_GT) return t > T + half;
  if (op == VFDSL_PM_GE) return t >= T - half;
  if (op == VFDSL_PM_LT) return t < T - half;
  return t <= T + half;
}

/* The Kleene value of a postfix program over the monitors' values. */
static int vfdsl_pm_run(const int* code, int size, const int* value) {
  int stack[VFDSL_PM_MAX_STACK], top = -1, k, a, b, absorbing;
  for (k=0; k<size; ++k) {
    int op = code[k];
    if (op >= 0) { stack[++top] = value[op]; continue; }
    if (op == VFDSL_PM_NOT) { if (stack[top] != VFDSL_PM_UNKNOWN) stack[top] = 1 - stack[top]; continue; }
    b = stack[top--]; a = stack[top];
    absorbing = op == VFDSL_PM_AND ? VFDSL_PM_FALSE : VFDSL_PM_TRUE;
    stack[top] = a == absorbing || b == absorbing ? absorbing : (a == b ? a : VFDSL_PM_UNKNOWN);
  }
  return stack[0];
}

static int vfdsl_pm_condition(const vfdsl_pm_table* T, vfdsl_pm_state* S, int i, const double* raw,
                              const double* u, double dt, int last_status) {
  int kind = T->kind[i], j;
  double v;
  if (kind == VFDSL_PM_COMPARE) {
    v = raw[T->b[i] < 0 || !S->latch[i] ? T->a[i] : T->b[i]];
    if (isnan(v)) return VFDSL_PM_UNKNOWN;
    if (T->b[i] < 0) return v > 0.0;
    return S->latch[i] = v > 0.0;
  }
  if (kind == VFDSL_PM_ELAPSED) return vfdsl_pm_compare_time(S->elapsed, T->op[i], T->threshold[i], dt);
  if (kind == VFDSL_PM_UNCHANGED) {
    for (j=0; j<T->watch_size[T->a[i]]; ++j)
      if (isnan(u[T->watch_start[T->a[i]] + j])) return VFDSL_PM_UNKNOWN;
    return vfdsl_pm_compare_time(S->unchanged[T->a[i]], T->op[i], T->threshold[i], dt);
  }
  if (kind == VFDSL_PM_LEAST_VIOLATION) return (last_status & VFDSL_PM_LEAST_VIOLATION_BIT) != 0;
  return vfdsl_pm_run(T->code + T->a[i], T->b[i], S->value);
}

static int vfdsl_pm_advance(const vfdsl_pm_table* T, vfdsl_pm_state* S, const double* raw, const double* u,
                            double dt, int last_status) {
  int i, j, k, same, c;
  double t, s, w;
  if (!(dt >= 0.0 && dt < INFINITY)) dt = 0.0;
  if (S->started) S->elapsed += dt;
  S->started = 1;
  for (i=0; i<T->n_watched; ++i) {
    double* last = S->last + T->watch_offset[i];
    same = 1;
    for (j=0; j<T->watch_size[i]; ++j) {
      double x = u[T->watch_start[i] + j];
      same = same && x == last[j];
      last[j] = x;
    }
    S->unchanged[i] = same ? S->unchanged[i] + dt : 0.0;
  }
  for (i=0; i<T->n_monitors; ++i) {
    c = vfdsl_pm_condition(T, S, i, raw, u, dt, last_status);
    S->held[i] = c == VFDSL_PM_TRUE ? S->held[i] + dt : 0.0;
    S->value[i] = c == VFDSL_PM_TRUE && !vfdsl_pm_reached(S->held[i], T->hold[i], dt) ? VFDSL_PM_FALSE : c;
  }
  S->fired = -1;
  if (!T->final[S->phase])
    for (k=0; k<T->n_transitions; ++k)
      if ((T->source[k] == S->phase || (T->source[k] < 0 && T->target[k] != S->phase))
          && vfdsl_pm_run(T->code + T->guard_start[k], T->guard_size[k], S->value) == VFDSL_PM_TRUE) {
        S->fired = k; S->phase = T->target[k]; S->elapsed = 0.0; S->blend = T->blend[k];
        for (i=0; i<T->n_phases; ++i) S->start[i] = S->weight[i];
        break;
      }
  t = S->elapsed + dt;
  s = S->blend <= 0.0 || vfdsl_pm_reached(t, S->blend, dt) ? 1.0 : t / S->blend;
  for (i=0; i<T->n_phases; ++i) {
    w = S->start[i] + s * ((i == S->phase ? 1.0 : 0.0) - S->start[i]);
    S->weight[i] = w < 0.0 ? 0.0 : (w > 1.0 ? 1.0 : w);
  }
  S->funnel = 1.0 - s;
  return S->fired;
}

#endif
