/* The exported C tick timed from C: no Python in the process (benchmarks/export_tick.py builds and runs it).
 *
 * Compiled with -include <api>.h -DAPI=<api> and linked with lib<api>.a. Reads recorded states from stdin (one
 * tick per line: q, then the inputs), then calls <api>_step on them in turn (cycling) for WARMUP + TICKS ticks,
 * each timed with clock_gettime(CLOCK_MONOTONIC) around the call. Prints: median_us p99_us max_us ticks optimal.
 *
 *     ./export_tick TICKS DT < states.txt
 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define F(name) CAT(API, name)
#define MAX_STATES 10000
#define WIDTH 64
#define WARMUP 1000

static double states[MAX_STATES][WIDTH];

static int by_value(const void* a, const void* b) {
  long long x = *(const long long*) a, y = *(const long long*) b;
  return (x > y) - (x < y);
}

int main(int argc, char** argv) {
  long ticks = argc > 1 ? atol(argv[1]) : 100000, k;
  double dt = argc > 2 ? atof(argv[2]) : F(_default_period)(), dq[WIDTH];
  int nq = F(_num_joints)(), width = nq + F(_input_length)(), n = 0, j;
  long optimal = 0;
  long long* ns = (long long*) malloc(sizeof(long long) * ticks);
  API* ctrl = F(_new)();
  if (!ns || !ctrl || width > WIDTH) { fprintf(stderr, "setup failed\n"); return 2; }
  while (n < MAX_STATES) {
    for (j=0; j<width; ++j) if (scanf("%lf", &states[n][j]) != 1) goto read;
    ++n;
  }
read:
  if (n == 0) { fprintf(stderr, "no states on stdin\n"); return 2; }
  for (k=0; k<WARMUP + ticks; ++k) {
    struct timespec t0, t1;
    const double* s = states[k % n];
    int status;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    status = F(_step)(ctrl, s, s + nq, dt, dq);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (status < 0) { fprintf(stderr, "tick %ld refused: %s\n", k, F(_error_message)(status)); return 1; }
    if (k >= WARMUP) {
      ns[k - WARMUP] = (t1.tv_sec - t0.tv_sec) * 1000000000LL + (t1.tv_nsec - t0.tv_nsec);
      optimal += status == VF_OPTIMAL;
    }
  }
  qsort(ns, ticks, sizeof(long long), by_value);
  printf("%.3f %.3f %.3f %ld %ld\n", ns[ticks / 2] / 1e3, ns[(long) (0.99 * (ticks - 1))] / 1e3,
         ns[ticks - 1] / 1e3, ticks, optimal);
  F(_free)(ctrl);
  free(ns);
  return 0;
}
