/* Counts heap calls of a generated step function, tick by tick.
 *
 * Linked with the generated C, DAQP's static library and -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,
 * --wrap=free, so every heap call of the generated code and of DAQP goes through the counters below.
 * STEP is the step function's C name. Reads ticks from stdin: per tick, the values of every input in
 * order (q, u, p, dt, recover), whitespace-separated. Writes one line per tick:
 *     <heap calls during the call> <return code> <status> <x_0> ... <x_{n-1}>
 */
#include <stdio.h>
#include <stdlib.h>

#define CONCAT_(a, b) a##b
#define CONCAT(a, b) CONCAT_(a, b)
#define CALL(suffix) CONCAT(STEP, suffix)

typedef long long int casadi_int;
int STEP(const double** arg, double** res, casadi_int* iw, double* w, int mem);
int CALL(_work)(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w);
const casadi_int* CALL(_sparsity_in)(casadi_int i);
const casadi_int* CALL(_sparsity_out)(casadi_int i);
casadi_int CALL(_n_in)(void);
casadi_int CALL(_n_out)(void);
void CALL(_incref)(void);
int CALL(_checkout)(void);

static long heap_calls = 0;
void* __real_malloc(size_t size);
void* __real_calloc(size_t count, size_t size);
void* __real_realloc(void* p, size_t size);
void __real_free(void* p);
void* __wrap_malloc(size_t size) { ++heap_calls; return __real_malloc(size); }
void* __wrap_calloc(size_t count, size_t size) { ++heap_calls; return __real_calloc(count, size); }
void* __wrap_realloc(void* p, size_t size) { ++heap_calls; return __real_realloc(p, size); }
void __wrap_free(void* p) { if (p) ++heap_calls; __real_free(p); }

static casadi_int numel(const casadi_int* sp) { return sp[0] * sp[1]; }

int main(void) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w, i, k;
  casadi_int n_in = CALL(_n_in)(), n_out = CALL(_n_out)();
  CALL(_work)(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const double** arg = calloc(sz_arg, sizeof(double*));
  double** res = calloc(sz_res, sizeof(double*));
  casadi_int* iw = calloc(sz_iw + 1, sizeof(casadi_int));
  double* w = calloc(sz_w + 1, sizeof(double));
  for (i = 0; i < n_in; ++i) arg[i] = calloc(numel(CALL(_sparsity_in)(i)) + 1, sizeof(double));
  for (i = 0; i < n_out; ++i) res[i] = calloc(numel(CALL(_sparsity_out)(i)) + 1, sizeof(double));
  CALL(_incref)();
  int mem = CALL(_checkout)();
  for (;;) {
    for (i = 0; i < n_in; ++i) {
      double* a = (double*) arg[i];
      for (k = 0; k < numel(CALL(_sparsity_in)(i)); ++k) {
        if (scanf("%lf", &a[k]) != 1) return 0;
      }
    }
    heap_calls = 0;
    int code = STEP(arg, res, iw, w, mem);
    long calls = heap_calls;
    printf("%ld %d %.17g", calls, code, res[1][0]);
    for (k = 0; k < numel(CALL(_sparsity_out)(0)); ++k) printf(" %.17g", res[0][k]);
    printf("\n");
  }
}
