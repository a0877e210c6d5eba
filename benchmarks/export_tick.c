/* The exported C tick timed from C: no Python in the process (benchmarks/export_tick.py builds and runs it).
 *
 * Compiled with -include <api>.h -DAPI=<api> and linked with lib<api>.a. Reads recorded states from stdin (one
 * tick per line: q, then the inputs), then calls <api>_step on them in turn (cycling) for WARMUP + TICKS ticks,
 * each timed around the call twice: wall time (clock_gettime(CLOCK_MONOTONIC)) and the thread's CPU time
 * (CLOCK_THREAD_CPUTIME_ID: what the tick itself cost, without the time another process held the core). Prints one
 * line: median_us p99_us p999_us max_us of the wall times, the same four of the CPU times, ticks, optimal.
 *
 *     ./export_tick TICKS DT < states.txt
 */
#include "quantiles.h"

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define F(name) CAT(API, name)
#define MAX_STATES 10000
#define WIDTH 64
#define WARMUP 1000

static double states[MAX_STATES][WIDTH];

int main(int argc, char** argv) {
  long ticks = argc > 1 ? atol(argv[1]) : 100000, k;
  double dt = argc > 2 ? atof(argv[2]) : F(_default_period)(), dq[WIDTH];
  int nq = F(_num_joints)(), width = nq + F(_input_length)(), n = 0, j;
  long optimal = 0;
  long long* ns = (long long*) malloc(sizeof(long long) * ticks);
  long long* cpu = (long long*) malloc(sizeof(long long) * ticks);
  API* ctrl = F(_new)();
  if (!ns || !cpu || !ctrl || width > WIDTH) { fprintf(stderr, "setup failed\n"); return 2; }
  while (n < MAX_STATES) {
    for (j=0; j<width; ++j) if (scanf("%lf", &states[n][j]) != 1) goto read;
    ++n;
  }
read:
  if (n == 0) { fprintf(stderr, "no states on stdin\n"); return 2; }
  for (k=0; k<WARMUP + ticks; ++k) {
    struct timespec t0, t1, c0, c1;
    const double* s = states[k % n];
    int status;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    status = F(_step)(ctrl, s, s + nq, dt, dq);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
    if (status < 0) { fprintf(stderr, "tick %ld refused: %s\n", k, F(_error_message)(status)); return 1; }
    if (k >= WARMUP) {
      ns[k - WARMUP] = elapsed_ns(&t0, &t1);
      cpu[k - WARMUP] = elapsed_ns(&c0, &c1);
      optimal += status == VF_OPTIMAL;
    }
  }
  print_quantiles(ns, ticks);
  print_quantiles(cpu, ticks);
  printf("%ld %ld\n", ticks, optimal);
  F(_free)(ctrl);
  free(ns);
  free(cpu);
  return 0;
}
