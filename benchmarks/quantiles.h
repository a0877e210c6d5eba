/* What the C timing programs of benchmarks/ share (export_tick.c, mesh_query.c): a span of clock_gettime in ns, and
 * the median, p99, p99.9 and max of many of them. */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static long long elapsed_ns(const struct timespec* t0, const struct timespec* t1) {
  return (t1->tv_sec - t0->tv_sec) * 1000000000LL + (t1->tv_nsec - t0->tv_nsec);
}

static int by_value(const void* a, const void* b) {
  long long x = *(const long long*) a, y = *(const long long*) b;
  return (x > y) - (x < y);
}

/* Sorts x (n values, ns) and prints its median, p99, p99.9 and max in us, each followed by a space. */
static void print_quantiles(long long* x, long n) {
  qsort(x, n, sizeof(long long), by_value);
  printf("%.3f %.3f %.3f %.3f ", x[n / 2] / 1e3, x[(long) (0.99 * (n - 1))] / 1e3, x[(long) (0.999 * (n - 1))] / 1e3,
         x[n - 1] / 1e3);
}
