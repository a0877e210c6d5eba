/* The run-time contract of an exported library, from C (tests/test_export.py builds and runs it).
 *
 * Compiled with -include <api>.h -DAPI=<api>, linked with lib<api>.a. Reads ticks from stdin (replay's
 * format: q, then the inputs, one tick per line; at most MAX_TICKS) and runs one mode:
 *
 *   leaks    three controllers made, stepped over every tick and freed, twice (run it under
 *            AddressSanitizer: a leak or a bad access fails the process); prints "ok"
 *   alloc    with malloc, calloc, realloc and free wrapped (-Wl,--wrap=...): one controller; prints the heap
 *            calls of _new, then of all ticks, set_param (accepted and refused), violations, error_message,
 *            a procedure's _phase, _transition, _monitor and _reset
 *   threads  two threads, each with its own controller, over every tick, against the same ticks run
 *            alone first: prints the number of ticks whose dq or status differ (0 expected)
 *   busy     one controller, two threads calling _step with the first tick until a call was refused: prints
 *            the refused calls, the calls answered wrongly (dq not the answer alone, or not zeros when refused)
 *            and the calls answered (expected: > 0, 0, > 0)
 *   refuse   per tick, _step with dq_out filled with ones first: the code and 1 if dq_out is all zeros after
 *   params   stdin holds param vectors instead (_param_length() numbers each): per vector, _set_params's code,
 *            _error_check and _error_index on one controller (refused vectors leave the params unchanged)
 *   errors   per line "what code index check": each kind of refusal after a refusal of another kind (the index
 *            and check must be the last error's), then "strings N" (the NULL strings of the string functions
 *            out of range; 0 expected)
 *   readers  steps the first tick over and over while a signal handler (every ms of CPU time, 100 times)
 *            calls _violations, _error_index and _error_check, mostly in the middle of a step: prints the
 *            readers' refused calls, their wrong answers (not the answer alone) and the answered calls
 *            (expected: > 0, 0, any)
 */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <signal.h>
#include <string.h>
#include <sys/time.h>

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define F(name) CAT(API, name)
#define MAX_TICKS 4096
#define WIDTH 256

typedef API controller;

static double ticks[MAX_TICKS][WIDTH];
static int n_ticks, nq, nu;
static double dt;

static void read_ticks(void) {
  int width = nq + nu, k;
  while (n_ticks < MAX_TICKS) {
    for (k=0; k<width; ++k) if (scanf("%lf", &ticks[n_ticks][k]) != 1) return;
    ++n_ticks;
  }
}

/* Every tick on a fresh controller: statuses and dq (nq per tick) into out. */
static void run_all(controller* c, int* status, double* dq) {
  int k;
  for (k=0; k<n_ticks; ++k) status[k] = F(_step)(c, ticks[k], ticks[k] + nq, dt, dq + k * nq);
}

/* ------------------------------------------------------------------------------------------ leaks */
static int leaks(void) {
  static double dq[MAX_TICKS * WIDTH];
  static int status[MAX_TICKS];
  int round, i;
  for (round=0; round<2; ++round) {
    controller* c[3];
    for (i=0; i<3; ++i) c[i] = F(_new)();
    for (i=0; i<3; ++i) {
      if (!c[i]) { printf("_new failed\n"); return 1; }
      run_all(c[i], status, dq);
    }
    for (i=0; i<3; ++i) F(_free)(c[i]);
  }
  printf("ok\n");
  return 0;
}

/* ------------------------------------------------------------------------------------------ alloc */
static long heap_calls = 0;
void* __real_malloc(size_t size);
void* __real_calloc(size_t count, size_t size);
void* __real_realloc(void* p, size_t size);
void __real_free(void* p);
#ifdef COUNT_HEAP
void* __wrap_malloc(size_t size) { __atomic_add_fetch(&heap_calls, 1, __ATOMIC_RELAXED); return __real_malloc(size); }
void* __wrap_calloc(size_t n, size_t size) { __atomic_add_fetch(&heap_calls, 1, __ATOMIC_RELAXED); return __real_calloc(n, size); }
void* __wrap_realloc(void* p, size_t size) { __atomic_add_fetch(&heap_calls, 1, __ATOMIC_RELAXED); return __real_realloc(p, size); }
void __wrap_free(void* p) { if (p) __atomic_add_fetch(&heap_calls, 1, __ATOMIC_RELAXED); __real_free(p); }
#endif

static int alloc(void) {
  static double dq[MAX_TICKS * WIDTH];
  static int status[MAX_TICKS];
  double values[WIDTH], bad[WIDTH];
  F(_violation) found[16];
  long at_new, ticked, params;
  int k;
  controller* c;
  heap_calls = 0;
  c = F(_new)();
  at_new = heap_calls;
  heap_calls = 0;
  run_all(c, status, dq);
  ticked = heap_calls;
  heap_calls = 0;
  for (k=0; k<F(_num_params)(); ++k) {
    memcpy(values, F(_param_default)(k), sizeof(double) * F(_param_size)(k));
    memcpy(bad, values, sizeof(double) * F(_param_size)(k));
    bad[0] = NAN;
    F(_set_param)(c, k, values);
    F(_set_param)(c, k, bad);
  }
  F(_violations)(c, found, 16);
  F(_error_message)(VF_ERR_PARAM);
  F(_phase)(c); F(_transition)(c); F(_monitor)(c, 0); F(_reset)(c);     /* a procedure's readers and reset */
  F(_step)(c, ticks[0], ticks[0] + nq, dt, dq);
  params = heap_calls;
  F(_free)(c);
  printf("%ld %ld %ld\n", at_new, ticked, params);
  return 0;
}

/* ---------------------------------------------------------------------------------------- threads */
typedef struct {
  controller* c;
  int status[MAX_TICKS];
  double dq[MAX_TICKS * 32];
} run;

static void* run_thread(void* arg) {
  run* r = (run*) arg;
  run_all(r->c, r->status, r->dq);
  return 0;
}

static int threads(void) {
  static run alone, both[2];
  pthread_t t[2];
  int i, k, j, differ = 0;
  alone.c = F(_new)();
  run_all(alone.c, alone.status, alone.dq);
  F(_free)(alone.c);
  for (i=0; i<2; ++i) both[i].c = F(_new)();
  for (i=0; i<2; ++i) pthread_create(&t[i], 0, run_thread, &both[i]);
  for (i=0; i<2; ++i) pthread_join(t[i], 0);
  for (i=0; i<2; ++i) {
    for (k=0; k<n_ticks; ++k) {
      int same = both[i].status[k] == alone.status[k];
      for (j=0; j<nq; ++j) same = same && both[i].dq[k * nq + j] == alone.dq[k * nq + j];
      differ += !same;
    }
    F(_free)(both[i].c);
  }
  printf("%d\n", differ);
  return 0;
}

/* ------------------------------------------------------------------------------------------- busy */
typedef struct {
  controller* c;
  const double* reference;
  int reference_status;
  long refused, wrong, answered;
  volatile int* stop;
} hammer;

static void* hammer_thread(void* arg) {
  hammer* h = (hammer*) arg;
  double dq[32];
  long calls;
  int j;
  for (calls=0; calls<2000000 && !*h->stop; ++calls) {
    int s = F(_step)(h->c, ticks[0], ticks[0] + nq, dt, dq);
    if (s == VF_ERR_BUSY) {
      int zero = 1;
      for (j=0; j<nq; ++j) zero = zero && dq[j] == 0;
      ++h->refused;
      h->wrong += !zero;
      if (h->refused >= 100) *h->stop = 1;
      continue;
    }
    ++h->answered;
    int same = s == h->reference_status;
    for (j=0; j<nq; ++j) same = same && dq[j] == h->reference[j];
    h->wrong += !same;
  }
  return 0;
}

static int busy(void) {
  static double reference[32];
  volatile int stop = 0;
  hammer h[2];
  pthread_t t[2];
  int i, status;
  controller* c = F(_new)();
  /* The answer alone, twice: the second call starts from the first one's working set, as every later one. */
  F(_step)(c, ticks[0], ticks[0] + nq, dt, reference);
  status = F(_step)(c, ticks[0], ticks[0] + nq, dt, reference);
  for (i=0; i<2; ++i) {
    h[i].c = c; h[i].reference = reference; h[i].reference_status = status;
    h[i].refused = h[i].wrong = h[i].answered = 0; h[i].stop = &stop;
    pthread_create(&t[i], 0, hammer_thread, &h[i]);
  }
  for (i=0; i<2; ++i) pthread_join(t[i], 0);
  F(_free)(c);
  printf("%ld %ld %ld\n", h[0].refused + h[1].refused, h[0].wrong + h[1].wrong, h[0].answered + h[1].answered);
  return 0;
}

/* ----------------------------------------------------------------------------------------- errors */
static void report(controller* c, const char* what, int code) {
  printf("%s %d %d %d\n", what, code, F(_error_index)(c), F(_error_check)(c));
}

static int errors(void) {
  double p[WIDTH], dq[32];
  const int np = F(_param_length)(), last = F(_num_params)() - 1;
  int k, nulls = 0;
  controller* c = F(_new)();
  memcpy(p, F(_param_default)(0), sizeof(double) * np);
  p[np - 1] = NAN;                                             /* a NaN in the last param */
  report(c, "nan", F(_set_params)(c, p));
  report(c, "index", F(_set_param)(c, 99, p));                 /* then a wrong index: 99, not the NaN's */
  report(c, "nan", F(_set_param)(c, last, p + np - F(_param_size)(last)));
  report(c, "negative", F(_set_param)(c, -3, p));
  for (k=0; k<np; ++k) p[k] = 0;                               /* zeros: a check fails */
  report(c, "zeros", F(_set_params)(c, p));
  report(c, "null", F(_set_params)(c, 0));
  report(c, "step", F(_step)(c, ticks[0], ticks[0] + nq, dt, dq));
  report(c, "zeros", F(_set_params)(c, p));
  report(c, "q", F(_step)(c, ticks[1], ticks[1] + nq, dt, dq));
  F(_free)(c);
  nulls += !F(_check_meaning)(-1) + !F(_check_meaning)(-8) + !F(_check_meaning)(1 << 20);
  nulls += !F(_joint_name)(-1) + !F(_joint_unit)(nq) + !F(_input_name)(-1) + !F(_input_unit)(1 << 20);
  nulls += !F(_param_name)(-1) + !F(_param_type)(1 << 20) + !F(_param_unit)(-1) + !F(_row_label)(-1);
  nulls += !F(_error_message)(-1000) + !F(_error_message)(1);
  printf("strings %d\n", nulls);
  return 0;
}

/* ---------------------------------------------------------------------------------------- readers */
static controller* read_c;
static F(_violation) read_reference[16];
static int read_n, read_index;
static volatile long read_signals, read_refused, read_wrong, read_answered;

/* SIGPROF's handler: the readers, called while the loop below is (almost always) inside a step, as another
 * thread would call them; deterministic, unlike two threads on a loaded machine. */
static void read_during_step(int signal) {
  F(_violation) found[16];
  int n = F(_violations)(read_c, found, 16), index = F(_error_index)(read_c), check = F(_error_check)(read_c);
  int j, same = n == read_n;
  (void) signal;
  ++read_signals;
  read_refused += (n == VF_ERR_BUSY) + (index == VF_ERR_BUSY) + (check == VF_ERR_BUSY);
  if (n == VF_ERR_BUSY) return;
  for (j=0; j<n && j<16 && same; ++j) same = found[j].amount == read_reference[j].amount;
  read_wrong += !same + (index != VF_ERR_BUSY && index != read_index);
  ++read_answered;
}

static int readers(void) {
  double dq[32];
  struct itimerval every = {{0, 1000}, {0, 1000}}, off = {{0, 0}, {0, 0}};
  struct sigaction action;
  read_c = F(_new)();
  F(_step)(read_c, ticks[0], ticks[0] + nq, dt, dq);
  F(_step)(read_c, ticks[0], ticks[0] + nq, dt, dq);
  read_n = F(_violations)(read_c, read_reference, 16);
  read_index = F(_error_index)(read_c);
  memset(&action, 0, sizeof action);
  action.sa_handler = read_during_step;
  sigaction(SIGPROF, &action, 0);
  setitimer(ITIMER_PROF, &every, 0);                         /* every ms of CPU time */
  while (read_signals < 100) F(_step)(read_c, ticks[0], ticks[0] + nq, dt, dq);
  setitimer(ITIMER_PROF, &off, 0);
  F(_free)(read_c);
  printf("%ld %ld %ld\n", read_refused, read_wrong, read_answered);
  return 0;
}

/* ----------------------------------------------------------------------------------------- refuse */
static int refuse(void) {
  double dq[32];
  int k, j;
  controller* c = F(_new)();
  for (k=0; k<n_ticks; ++k) {
    int code, zero = 1;
    for (j=0; j<nq; ++j) dq[j] = 1.0;
    code = F(_step)(c, ticks[k], ticks[k] + nq, dt, dq);
    for (j=0; j<nq; ++j) zero = zero && dq[j] == 0.0;
    printf("%d %d\n", code, zero);
  }
  F(_free)(c);
  return 0;
}

/* ----------------------------------------------------------------------------------------- params */
static int params(void) {
  static double p[WIDTH * 64];
  int np = F(_param_length)(), k;
  controller* c = F(_new)();
  for (;;) {
    int code;
    for (k=0; k<np; ++k) if (scanf("%lf", &p[k]) != 1) { F(_free)(c); return 0; }
    code = F(_set_params)(c, p);
    printf("%d %d %d\n", code, F(_error_check)(c), F(_error_index)(c));
  }
}

int main(int argc, char** argv) {
  nq = F(_num_joints)();
  nu = F(_input_length)();
  dt = argc > 2 ? strtod(argv[2], 0) : F(_default_period)();
  if (nq > 32 || nq + nu > WIDTH) { printf("task too large for this harness\n"); return 2; }
  if (argc > 1 && !strcmp(argv[1], "params")) return params();
  read_ticks();
  if (argc < 2 || n_ticks == 0) { printf("usage: %s leaks|alloc|threads|busy|refuse|params|errors|readers [dt] < ticks\n", argv[0]); return 2; }
  if (!strcmp(argv[1], "leaks")) return leaks();
  if (!strcmp(argv[1], "alloc")) return alloc();
  if (!strcmp(argv[1], "threads")) return threads();
  if (!strcmp(argv[1], "busy")) return busy();
  if (!strcmp(argv[1], "refuse")) return refuse();
  if (!strcmp(argv[1], "errors")) return errors();
  if (!strcmp(argv[1], "readers")) return readers();
  printf("unknown mode %s\n", argv[1]);
  return 2;
}
