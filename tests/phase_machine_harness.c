/* Test harness: vfdsl/codegen/phase_machine.h run over a sequence of ticks, from Python through ctypes
 * (tests/test_phase_machine_twin.py).
 *
 *   void pm_run(table, ticks, raw, u, dt, status, state, out): the table as MachineTable.c_arrays() lays it out;
 *     raw (ticks x n_raw), u (ticks x n_u), dt and status per tick; state: the arrays vfdsl_pm_state points into;
 *     out: per tick the phase, the transition fired, the weights (n_phases), the funnel and the monitors' values.
 *   void pm_constants(int* out): the header's constants, in the order the test lists them. */
#include "phase_machine.h"

void pm_run(int n_phases, int initial, const int* final, int n_monitors, const int* kind, const int* a,
            const int* b, const int* op, const double* threshold, const double* hold, int n_watched,
            const int* watch_start, const int* watch_size, const int* watch_offset, int n_transitions,
            const int* source, const int* target, const int* guard_start, const int* guard_size,
            const double* blend, const int* code,
            int ticks, int n_raw, int n_u, const double* raw, const double* u, const double* dt, const int* status,
            int* latch, int* value, double* held, double* last, double* unchanged, double* start, double* weight,
            int* phase_out, int* fired_out, double* weight_out, double* funnel_out, int* value_out) {
  vfdsl_pm_table T = {n_phases, initial, final, n_monitors, kind, a, b, op, threshold, hold, n_watched,
                      watch_start, watch_size, watch_offset, n_transitions, source, target, guard_start,
                      guard_size, blend, code};
  vfdsl_pm_state S;
  int k, i;
  S.latch = latch; S.value = value; S.held = held; S.last = last; S.unchanged = unchanged;
  S.start = start; S.weight = weight;
  vfdsl_pm_init(&T, &S);
  for (k=0; k<ticks; ++k) {
    fired_out[k] = vfdsl_pm_advance(&T, &S, raw + k * n_raw, u + k * n_u, dt[k], status[k]);
    phase_out[k] = S.phase;
    funnel_out[k] = S.funnel;
    for (i=0; i<n_phases; ++i) weight_out[k * n_phases + i] = S.weight[i];
    for (i=0; i<n_monitors; ++i) value_out[k * n_monitors + i] = S.value[i];
  }
}

void pm_constants(int* out) {
  int c[] = {VFDSL_PM_FALSE, VFDSL_PM_TRUE, VFDSL_PM_UNKNOWN, VFDSL_PM_COMPARE, VFDSL_PM_ELAPSED,
             VFDSL_PM_UNCHANGED, VFDSL_PM_LEAST_VIOLATION, VFDSL_PM_LOGIC, VFDSL_PM_GT, VFDSL_PM_GE, VFDSL_PM_LT,
             VFDSL_PM_LE, VFDSL_PM_AND, VFDSL_PM_OR, VFDSL_PM_NOT, VFDSL_PM_MAX_STACK, VFDSL_PM_LEAST_VIOLATION_BIT};
  int i;
  for (i=0; i<(int) (sizeof c / sizeof c[0]); ++i) out[i] = c[i];
}
