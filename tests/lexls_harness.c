/* Test harness: vfdsl/codegen/lexls.c called on DAQP's data layout, from Python through ctypes (tests/test_lexls.py).
 *
 *   int lexls_solve(n, nh, break_points, H, f, A, lower, upper, s, x, repairs): as the generated tick tries a
 *     guess: solve over the working set s (K entries), x the answer, and on a refusal change s by the solver's
 *     hint, at most ``repairs`` times; returns the number of solves made when one was certified, 0 when none
 *     was, -1 out of memory.
 *   int lexls_from(n, nh, break_points, H, f, A, lower, upper, x): vfdsl_lex_from from x, a point of the hard
 *     rows: x its last iterate; 1 when certified, 0 not, -1 out of memory.
 *   void lexls_working_set(n, nh, break_points, A, lower, upper, x, s): the working set of x.
 * A is row-major (rows past the n simple bounds), lower/upper hold the n simple bounds first. */
#include "lexls.c"

static void problem(vfdsl_lex_prob* P, int n, int nh, const int* bp, const double* H, const double* f,
                    const double* A, const double* lower, const double* upper) {
  P->n = n; P->ms = n; P->K = bp[0] - n; P->nh = nh; P->break_points = bp;
  P->H = H; P->f = f; P->A = A; P->blower = lower; P->bupper = upper;
}

int lexls_solve(int n, int nh, const int* bp, const double* H, const double* f, const double* A,
                const double* lower, const double* upper, int* s, double* x, int repairs) {
  vfdsl_lex_prob P;
  vfdsl_lex* L;
  int r, solves = 0;
  problem(&P, n, nh, bp, H, f, A, lower, upper);
  L = vfdsl_lex_alloc(n, P.K, bp[nh - 1] - bp[0]);
  if (!L) return -1;
  vfdsl_lex_rows(L, &P);
  for (r=0;; ++r) {
    if (vfdsl_lex_solve(L, &P, s, x)) { solves = r + 1; break; }
    if (r == repairs || !vfdsl_lex_repair(L, s)) break;
  }
  vfdsl_lex_free(L);
  return solves;
}

/* vfdsl_lex_from from x (a point of the hard rows): x its last iterate; 1 certified, 0 not, -1 out of memory. */
int lexls_from(int n, int nh, const int* bp, const double* H, const double* f, const double* A,
               const double* lower, const double* upper, double* x) {
  vfdsl_lex_prob P;
  vfdsl_lex* L;
  int certified;
  problem(&P, n, nh, bp, H, f, A, lower, upper);
  L = vfdsl_lex_alloc(n, P.K, bp[nh - 1] - bp[0]);
  if (!L) return -1;
  vfdsl_lex_rows(L, &P);
  certified = vfdsl_lex_from(L, &P, L->guess, x);
  vfdsl_lex_free(L);
  return certified;
}

void lexls_working_set(int n, int nh, const int* bp, const double* A, const double* lower, const double* upper,
                       const double* x, int* s) {
  vfdsl_lex_prob P;
  vfdsl_lex* L;
  problem(&P, n, nh, bp, 0, 0, A, lower, upper);
  L = vfdsl_lex_alloc(n, P.K, bp[nh - 1] - bp[0]);
  if (!L) return;
  vfdsl_lex_rows(L, &P);
  vfdsl_lex_working_set(L, x, s);
  vfdsl_lex_free(L);
}
