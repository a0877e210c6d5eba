/* The mesh proximity query timed from C: no Python in the process (benchmarks/mesh.py builds and runs it).
 *
 * Compiled with the query's generated source (vfdsl/mesh/query.c below the mesh's tables), -DQUERY=<its name> and
 * -DROWS=<its K>.
 * Reads segments from stdin (one state per line: a, then b, in the mesh's frame, m), then calls the query on every
 * state in turn, ROUNDS times over (after one round of warm-up), each call timed twice: wall time
 * (clock_gettime(CLOCK_MONOTONIC)) and the thread's CPU time (CLOCK_THREAD_CPUTIME_ID). Prints two lines of eight
 * numbers, us: median, p99, p99.9 and max of the wall times, then the same of the CPU times,
 *   - over every call (the machine's interruptions included: what a control loop would see), and
 *   - over the states, of each state's median over the rounds (what the query costs at each state: a call that the
 *     shared machine interrupted once counts no more than its state's other calls).
 *
 *     ./mesh_query ROUNDS CUTOFF SIDE < segments.txt
 */
#include "quantiles.h"

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define MAX_STATES 10000

typedef long long int casadi_int;
int QUERY(const double** arg, double** res, casadi_int* iw, double* w, int mem);
int CAT(QUERY, _work)(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w);

static double segments[MAX_STATES][6];

int main(int argc, char** argv) {
  int rounds = argc > 1 ? atoi(argv[1]) : 5, n = 0, r, i, j;
  double options[2] = {argc > 2 ? atof(argv[2]) : 0.0035, argc > 3 ? atof(argv[3]) : -1.0};
  casadi_int size[4];
  if (rounds < 1) { fprintf(stderr, "ROUNDS must be at least 1\n"); return 2; }
  CAT(QUERY, _work)(size, size + 1, size + 2, size + 3);
  double* work = (double*) malloc(sizeof(double) * size[3]);
  double d[ROWS], s[ROWS], u[3 * ROWS];
  while (n < MAX_STATES) {
    for (j = 0; j < 6; ++j) if (scanf("%lf", &segments[n][j]) != 1) goto read;
    ++n;
  }
read:
  if (n == 0 || !work) { fprintf(stderr, "no segments on stdin\n"); return 2; }
  long long* wall = (long long*) malloc(sizeof(long long) * n * rounds);
  long long* cpu = (long long*) malloc(sizeof(long long) * n * rounds);
  long long* state_wall = (long long*) malloc(sizeof(long long) * n);
  long long* state_cpu = (long long*) malloc(sizeof(long long) * n);
  long long* one = (long long*) malloc(sizeof(long long) * rounds);
  if (!wall || !cpu || !state_wall || !state_cpu || !one) { fprintf(stderr, "out of memory\n"); return 2; }
  for (r = -1; r < rounds; ++r)
    for (i = 0; i < n; ++i) {
      const double* arg[3] = {segments[i], segments[i] + 3, options};
      double* res[3] = {d, s, u};
      struct timespec t0, t1, c0, c1;
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
      clock_gettime(CLOCK_MONOTONIC, &t0);
      int status = QUERY(arg, res, 0, work, 0);
      clock_gettime(CLOCK_MONOTONIC, &t1);
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
      if (status != 0) { fprintf(stderr, "the query failed at state %d\n", i); return 1; }
      if (r >= 0) { wall[(long) r * n + i] = elapsed_ns(&t0, &t1); cpu[(long) r * n + i] = elapsed_ns(&c0, &c1); }
    }
  for (i = 0; i < n; ++i) {
    for (r = 0; r < rounds; ++r) one[r] = wall[(long) r * n + i];
    qsort(one, rounds, sizeof(long long), by_value);
    state_wall[i] = one[rounds / 2];
    for (r = 0; r < rounds; ++r) one[r] = cpu[(long) r * n + i];
    qsort(one, rounds, sizeof(long long), by_value);
    state_cpu[i] = one[rounds / 2];
  }
  print_quantiles(wall, (long) n * rounds);
  print_quantiles(cpu, (long) n * rounds);
  printf("\n");
  print_quantiles(state_wall, n);
  print_quantiles(state_cpu, n);
  printf("\n");
  free(work); free(wall); free(cpu); free(state_wall); free(state_cpu); free(one);
  return 0;
}
