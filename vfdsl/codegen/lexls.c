/* vfdsl: priority levels solved exactly over a working set, with a certificate of optimality: the C of
 * vfdsl/runtime/lexls.py. The types and the API are in lexls.h.
 *
 * One file, over 500 lines, on purpose: it is the twin of lexls.py function for function (a test holds the two
 * to the same answers), and one translation unit, compiled once per n with VFDSL_LEX_N (vfdsl.codegen.build) and
 * copied as it is into an export, whose static kernels (QR, the steps, NNLS, the certificate) the compiler
 * inlines and unrolls within the unit. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lexls.h"

#define LEX_RANK_TOL 1e-10
#define LEX_COND_TOL 1e-4
#define LEX_PRIMAL_TOL 1e-9
#define LEX_DUAL_TOL 1e-9
#define LEX_ACTIVE_TOL 1e-9
#define LEX_DEGENERATE_DROPS 2
#define LEX_ROUNDING 2.220446049250313e-16
#ifndef LEX_PRIMAL_STEPS
#define LEX_PRIMAL_STEPS 50     /* lexls.py's PRIMAL_STEPS (a test builds it with another) */
#endif

/* The number of variables of a problem or a workspace X. A build defines VFDSL_LEX_N, the task's n (vfdsl.codegen.build
   compiles this file once per n): every loop over the variables then has a trip count known to the compiler, which
   unrolls it (experiment B's exact solve, in a C loop over recorded problems: 1.47 -> 1.21 us). */
#ifdef VFDSL_LEX_N
#define LEX_N(X) VFDSL_LEX_N
#else
#define LEX_N(X) ((X)->n)
#endif


void vfdsl_lex_free(vfdsl_lex* L) {
  free(L);                            /* the workspace and its arrays are one block (vfdsl_lex_alloc) */
}

static double* lex_doubles(double** at, size_t count) {
  double* taken = *at;
  *at += count;
  return taken;
}

static int* lex_ints(int** at, size_t count) {
  int* taken = *at;
  *at += count;
  return taken;
}

vfdsl_lex* vfdsl_lex_alloc(int n, int K, int P) {
  size_t N = (size_t) n, K1 = (size_t) K + 1;
  size_t R = (size_t) K + P + n;      /* most rows gathered at once (a step, or the fixed rows and every level) */
  size_t S = (size_t) P + 2;          /* most steps: W's, then one per level (a level has a row at least) */
  size_t head = (sizeof(vfdsl_lex) + sizeof(double) - 1) / sizeof(double) * sizeof(double);
  size_t doubles = 6 * K1 + 3 * R * N + 4 * R + 3 * N * N + 5 * N + 2 * N * K1 + (N + 1) + (N * N + 1)
                   + (P + 1) * (N + 1);
  size_t ints = 6 * K1 + 2 * R + 3 * S + 2 * (S + 1) + 2 * S;
  char* block;
  double* d;
  int* i;
  vfdsl_lex* L;
#ifdef VFDSL_LEX_N
  if (n != VFDSL_LEX_N) return 0;     /* compiled for another n: no exact solve (the caller keeps DAQP's answer) */
#endif
  /* one zeroed block: the struct, then its arrays of doubles, the rows' pointers and the ints (in that order, each
     aligned for the next) */
  block = (char*) calloc(1, head + doubles * sizeof(double) + S * sizeof(const double*) + ints * sizeof(int));
  if (!block) return 0;
  L = (vfdsl_lex*) block;
  L->n = n; L->K = K;
  d = (double*) (block + head);
  L->inv = lex_doubles(&d, K1); L->lo = lex_doubles(&d, K1); L->up = lex_doubles(&d, K1);
  L->M = lex_doubles(&d, R * N); L->t = lex_doubles(&d, R);
  L->B = lex_doubles(&d, R * N); L->T = lex_doubles(&d, R * N);
  L->tau = lex_doubles(&d, R); L->tau2 = lex_doubles(&d, R); L->c = lex_doubles(&d, R);
  L->Z = lex_doubles(&d, N * N); L->U = lex_doubles(&d, N * N);
  L->x = lex_doubles(&d, N); L->g = lex_doubles(&d, N); L->y = lex_doubles(&d, N); L->K2 = lex_doubles(&d, N * N);
  L->from_y = lex_doubles(&d, N); L->from_d = lex_doubles(&d, N);
  L->N = lex_doubles(&d, N * K1); L->NP = lex_doubles(&d, N * K1);
  L->lam = lex_doubles(&d, K1); L->sol = lex_doubles(&d, K1); L->w = lex_doubles(&d, K1);
  L->res = lex_doubles(&d, N + 1); L->fR = lex_doubles(&d, N * N + 1);
  L->LR = lex_doubles(&d, (P + 1) * N); L->lt = lex_doubles(&d, P + 1);
  L->rows = (const double**) d;
  i = (int*) (L->rows + S);
  L->guess = lex_ints(&i, K1); L->piv = lex_ints(&i, R); L->cols = lex_ints(&i, K1);
  L->drop = lex_ints(&i, K1); L->trial = lex_ints(&i, K1); L->pinned = lex_ints(&i, K1);
  L->max_steps = (int) S;
  L->off = lex_ints(&i, S); L->r = lex_ints(&i, S); L->p = lex_ints(&i, S);
  L->fpiv_at = lex_ints(&i, S + 1); L->fR_at = lex_ints(&i, S + 1);
  L->fpiv = lex_ints(&i, R); L->side = lex_ints(&i, K1);
  L->level_at = lex_ints(&i, S); L->level_rows = lex_ints(&i, S);
  return L;
}

static double lex_dot(const double* a, const double* b, int n) {
  double s = 0;
  int i;
  for (i=0;i<n;++i) s += a[i]*b[i];
  return s;
}

/* Householder QR of the k x p column-major matrix B (in place: R above the diagonal, reflectors below, tau),
 * with column pivoting when piv is given (piv[i]: the column of B's original i-th column's place). Returns the
 * rank (pivots > RANK_TOL); *ill is set to 1 + the position of the first counted pivot <= COND_TOL. Without pivoting, all min(k, p)
 * columns are reduced and the rank is not decided (returns min(k, p)). */
static int lex_qr(double* B, int k, int p, double* tau, int* piv, int* ill) {
  int j, c, i, best, t = k < p ? k : p;
  if (piv) for (i=0;i<p;++i) piv[i] = i;
  for (j=0;j<t;++j) {
    double alpha, beta, norm2, best2 = -1, *col = B + j*k;
    if (piv) {                      /* the remaining column of largest norm */
      best = j;
      for (c=j;c<p;++c) {
        double s = 0, *b = B + c*k;
        for (i=j;i<k;++i) s += b[i]*b[i];
        if (s > best2) { best2 = s; best = c; }
      }
      if (best != j) {
        double tmp;
        int ti = piv[j]; piv[j] = piv[best]; piv[best] = ti;
        for (i=0;i<k;++i) { tmp = B[i + j*k]; B[i + j*k] = B[i + best*k]; B[i + best*k] = tmp; }
      }
    }
    if (piv) norm2 = best2;        /* (that column's sum, term by term) */
    else for (norm2 = 0, i = j; i < k; ++i) norm2 += col[i]*col[i];
    if (piv) {
      double d = sqrt(norm2);
      if (!(d > LEX_RANK_TOL)) return j;
      if (d <= LEX_COND_TOL && !*ill) *ill = j + 1;
    }
    alpha = col[j];
    beta = norm2 > 0 ? -copysign(sqrt(norm2), alpha) : 0;
    if (beta == 0) { tau[j] = 0; continue; }
    tau[j] = (beta - alpha) / beta;
    {
      double scale = 1 / (alpha - beta);
      for (i=j+1;i<k;++i) col[i] *= scale;
    }
    col[j] = beta;
    for (c=j+1;c<p;++c) {
      double *b = B + c*k, w = b[j];
      for (i=j+1;i<k;++i) w += col[i]*b[i];
      w *= tau[j];
      b[j] -= w;
      for (i=j+1;i<k;++i) b[i] -= w*col[i];
    }
  }
  return t;
}

/* Least squares min |V z - c| for the k x q column-major V (k >= q, overwritten by its QR; tau: q entries): c
 * becomes Q'c, its first q entries z. 0, or -1 when a pivot of R is below 1e-12 (a column (nearly) dependent on
 * the others). */
static int lex_solve_columns(double* V, int k, int q, double* c, double* tau) {
  int i, l, ill = 0;
  lex_qr(V, k, q, tau, 0, &ill);
  for (l=0;l<q;++l) {              /* c = Q' c */
    double w = c[l];
    if (tau[l] == 0) continue;
    for (i=l+1;i<k;++i) w += V[i + l*k]*c[i];
    w *= tau[l];
    c[l] -= w;
    for (i=l+1;i<k;++i) c[i] -= w*V[i + l*k];
  }
  for (l=q-1;l>=0;--l) {           /* R z = c */
    double s = c[l];
    if (!(fabs(V[l + l*k]) > 1e-12)) return -1;
    for (i=l+1;i<q;++i) s -= V[l + i*k]*c[i];
    c[l] = s / V[l + l*k];
  }
  return 0;
}

/* Z (n x k, column-major) times the first r reflectors of lex_qr's B (k rows); Z = I (ident, n = k): the product
 * H_0 ... H_{r-1} formed from the last reflector back, each touching only its trailing rows and columns. */
static void lex_apply_right(double* Z, int n, int k, const double* B, const double* tau, int r, int ident) {
  int j, i, l;
  if (ident) {
    for (j=r-1;j>=0;--j) {
      const double* v = B + j*k;
      if (tau[j] == 0) continue;
      for (l=j;l<k;++l) {          /* column l of H_j Q, Q's rows j.. (rows < j of column l >= j are 0) */
        double w = Z[j + l*n];
        for (i=j+1;i<k;++i) w += v[i]*Z[i + l*n];
        w *= tau[j];
        Z[j + l*n] -= w;
        for (i=j+1;i<k;++i) Z[i + l*n] -= w*v[i];
      }
    }
    return;
  }
  for (j=0;j<r;++j) {
    const double* v = B + j*k;
    if (tau[j] == 0) continue;
    for (i=0;i<n;++i) {
      double w = Z[i + j*n];
      for (l=j+1;l<k;++l) w += Z[i + l*n]*v[l];
      w *= tau[j];
      Z[i + j*n] -= w;
      for (l=j+1;l<k;++l) Z[i + l*n] -= w*v[l];
    }
  }
}

/* One step of the null-space chain: the rows M (p x n, row-major) against the k columns of *Z (n x k, column-major).
 * With t (targets), x moves by the least-squares step of M (x + Z y) = t within range(Z). range(Z) is split as
 * [Y | N] (N: the null space of M Z, Y its r columns before it); *Z moves past Y to N and *k drops by r. rec >= 0
 * records the step's factors as step rec (lexls.h). Returns 0, or -1 when a pivot is ill-conditioned. */
static int lex_step(vfdsl_lex* L, const double* M, int p, const double* t, double* x, double** Zp, int* k, int* ident,
                    int rec) {
  int n = LEX_N(L), kk = *k, r = 0, i, l, ill = 0;
  double *B = L->B, *Z = *Zp;
  if (kk && p) {
    if (*ident) memcpy(B, M, sizeof(double) * n * p);     /* Z = I: (M Z)' is M' (row-major M, column-major B) */
    else for (i=0;i<p;++i) for (l=0;l<kk;++l) B[l + i*kk] = lex_dot(M + i*n, Z + l*n, n);   /* (M Z)' */
    r = lex_qr(B, kk, p, L->tau, L->piv, &ill);
    if (ill && !L->ill_ok) { L->ill_at = ill - 1; return -1; }
  }
  if (rec >= 0) {
    L->steps = rec + 1;
    L->rows[rec] = M; L->p[rec] = p; L->r[rec] = r; L->off[rec] = (int) (Z - L->Z) / n;
    L->fpiv_at[rec + 1] = L->fpiv_at[rec] + p;
    L->fR_at[rec + 1] = L->fR_at[rec] + r*r;
    if (r) memcpy(L->fpiv + L->fpiv_at[rec], L->piv, sizeof(int) * p);
    for (l=0;l<r;++l) for (i=0;i<r;++i) L->fR[L->fR_at[rec] + i + l*r] = i <= l ? B[i + l*kk] : 0;
  }
  if (r == 0) return 0;
  lex_apply_right(Z, n, kk, B, L->tau, r, *ident);
  *ident = 0;
  if (t) {      /* z = argmin |R1' z - c|, c = (t - M x)[piv]; x += Z z */
    double *c = L->c;
    for (i=0;i<p;++i) c[i] = t[L->piv[i]] - lex_dot(M + L->piv[i]*n, x, n);
    if (r == p) {                    /* R1' lower triangular */
      for (i=0;i<p;++i) {
        for (l=0;l<i;++l) c[i] -= B[l + i*kk]*c[l];
        c[i] /= B[i + i*kk];
      }
    } else {                         /* QR of R1' (p x r) */
      for (l=0;l<r;++l) for (i=0;i<p;++i) L->T[i + l*p] = i >= l ? B[l + i*kk] : 0;
      if (lex_solve_columns(L->T, p, r, c, L->tau2) < 0) return -1;
    }
    for (l=0;l<r;++l) for (i=0;i<n;++i) x[i] += Z[i + l*n]*c[l];
  }
  *Zp = Z + r*n;
  *k = kk - r;
  return 0;
}

/* Cholesky solve of the k x k SPD K2 (column-major, overwritten) against b (overwritten by the solution); 0, or -1
 * when K2 is not positive definite. */
static int lex_cholesky_solve(double* K2, int k, double* b) {
  int i, j, l;
  for (j=0;j<k;++j) {
    double d = K2[j + j*k];
    for (l=0;l<j;++l) d -= K2[j + l*k]*K2[j + l*k];
    if (!(d > 0)) return -1;
    d = sqrt(d);
    K2[j + j*k] = d;
    for (i=j+1;i<k;++i) {
      double s = K2[i + j*k];
      for (l=0;l<j;++l) s -= K2[i + l*k]*K2[j + l*k];
      K2[i + j*k] = s / d;
    }
  }
  for (i=0;i<k;++i) { for (l=0;l<i;++l) b[i] -= K2[i + l*k]*b[l]; b[i] /= K2[i + i*k]; }
  for (i=k-1;i>=0;--i) { for (l=i+1;l<k;++l) b[i] -= K2[l + i*k]*b[l]; b[i] /= K2[i + i*k]; }
  return 0;
}

/* |N lam - c| for lam >= 0 (N k x a, column-major), plus its rounding, LEX_ROUNDING per unit of lam (N's columns are
 * unit rows projected: lexls.py's _rounding of the unprojected columns). */
static double lex_residual(const double* N, int k, int a, const double* c, const double* lam) {
  int i, j;
  double norm = 0, charge = 0;
  for (i=0;i<k;++i) { double r = c[i]; for (j=0;j<a;++j) r -= N[i + j*k]*lam[j]; norm += r*r; }
  for (j=0;j<a;++j) charge += LEX_ROUNDING * fabs(lam[j]);
  return sqrt(norm) + charge;
}

/* Least squares on the columns idx[0..q) of N (k x a): sol[idx[l]] = argmin |N_idx s - c|; 0, or -1 when a column
 * is (nearly) dependent on the others. */
static int lex_ls_columns(vfdsl_lex* L, const double* N, int k, const int* idx, int q, const double* c) {
  int l;
  if (q > k) return -1;
  for (l=0;l<q;++l) memcpy(L->NP + l*k, N + idx[l]*k, sizeof(double) * k);
  memcpy(L->res, c, sizeof(double) * k);
  if (lex_solve_columns(L->NP, k, q, L->res, L->tau2) < 0) return -1;
  for (l=0;l<q;++l) L->sol[idx[l]] = L->res[l];
  return 0;
}

/* 1 when min |N lam - c| over lam >= 0 is at most thr (N k x a, column-major): first the least squares over
 * every column with its negative entries set to 0 (any lam >= 0 bounds the minimum), then Lawson-Hanson, which
 * stops with the lam it has when a passive set's columns are (nearly) dependent. */
static int lex_nnls_within(vfdsl_lex* L, const double* N, int k, int a, const double* c, double thr) {
  double *lam = L->lam, *sol = L->sol, *w = L->w, *res = L->res;
  int *passive = L->cols, *idx = L->piv, i, j, l, iter;
  double tol = 0, cc = 0;
  for (j=0;j<a;++j) { lam[j] = 0; passive[j] = 0; idx[j] = j; for (i=0;i<k;++i) tol += fabs(N[i + j*k]); }
  for (i=0;i<k;++i) cc += c[i]*c[i];
  tol *= 10 * 2.220446049250313e-16 * (k > a ? k : a) * sqrt(cc);   /* w = N'(c - N lam) scales as c */
  L->hint_column = -1;
  if (lex_ls_columns(L, N, k, idx, a, c) == 0) {
    double most = 0;
    for (j=0;j<a;++j) {
      lam[j] = sol[j] > 0 ? sol[j] : 0;
      if (sol[j] < most) { most = sol[j]; L->hint_column = j; }
    }
    if (lex_residual(N, k, a, c, lam) <= thr) return 1;
    for (j=0;j<a;++j) lam[j] = 0;
  }
  for (iter=0; iter<3*a+3; ++iter) {
    int t = -1, inner;
    double best = tol;
    for (i=0;i<k;++i) { res[i] = c[i]; for (j=0;j<a;++j) res[i] -= N[i + j*k]*lam[j]; }
    for (j=0;j<a;++j) if (!passive[j]) {
      w[j] = lex_dot(N + j*k, res, k);
      if (w[j] > best) { best = w[j]; t = j; }
    }
    if (t < 0) break;
    passive[t] = 1;
    for (inner=0; inner<3*a+3; ++inner) {    /* least squares on the passive columns, kept >= 0 */
      int q = 0, neg = 0;
      double alpha = 1;
      for (j=0;j<a;++j) if (passive[j]) idx[q++] = j;
      if (lex_ls_columns(L, N, k, idx, q, c) < 0) {     /* a column (nearly) dependent on the others: lam as it is */
        iter = 3*a+3;
        break;
      }
      for (l=0;l<q;++l) if (sol[idx[l]] <= 0) neg = 1;
      if (!neg) { for (l=0;l<q;++l) lam[idx[l]] = sol[idx[l]]; break; }
      for (l=0;l<q;++l) {
        j = idx[l];
        if (sol[j] <= 0) { double step = lam[j] / (lam[j] - sol[j]); if (step < alpha) alpha = step; }
      }
      for (l=0;l<q;++l) {
        j = idx[l];
        lam[j] += alpha * (sol[j] - lam[j]);
        if (lam[j] <= tol) { lam[j] = 0; passive[j] = 0; }
      }
    }
  }
  return lex_residual(N, k, a, c, lam) <= thr;
}


/* The hard rows' lengths and unit bounds, and the levels' rows but those zero with a zero target, into L (every
   tick). */
void vfdsl_lex_rows(vfdsl_lex* L, const vfdsl_lex_prob* P) {
  int i, j, c, n = LEX_N(P), at = 0;
  L->A = P->A;
  for (i=0;i<P->K;++i) {
    double norm = sqrt(lex_dot(P->A + i*n, P->A + i*n, n)), scale = norm > 0 ? 1 / norm : 1;
    L->inv[i] = scale;
    L->lo[i] = P->blower[P->ms + i]*scale;
    L->up[i] = P->bupper[P->ms + i]*scale;
  }
  L->levels = 0;
  for (j=0;j<P->nh - 1;++j) {
    const double *R = P->A + (P->break_points[j] - P->ms)*n, *r = P->blower + P->break_points[j];
    int rows = P->break_points[j + 1] - P->break_points[j], kept = 0;
    for (i=0;i<rows;++i) {
      int zero = r[i] == 0;
      for (c=0; zero && c<n; ++c) zero = R[i*n + c] == 0;
      if (zero) continue;
      memcpy(L->LR + (at + kept)*n, R + i*n, sizeof(double) * n);
      L->lt[at + kept++] = r[i];
    }
    if (kept) {
      L->level_at[L->levels] = at;
      L->level_rows[L->levels++] = kept;
      at += kept;
    }
  }
  L->level_at[L->levels] = at;        /* (the rows above the last cost) */
}

/* Hard row i, of unit length, into out. */
static void lex_unit_row(const vfdsl_lex* L, int i, double* out) {
  int j;
  for (j=0;j<LEX_N(L);++j) out[j] = L->A[i*LEX_N(L) + j]*L->inv[i];
}

/* The working set of x (vfdsl.runtime.lexls.working_set). */
void vfdsl_lex_working_set(const vfdsl_lex* L, const double* x, int* s) {
  int i;
  for (i=0;i<L->K;++i) {
    double ax = lex_dot(L->A + i*LEX_N(L), x, LEX_N(L))*L->inv[i];
    int near_up = ax >= L->up[i] - LEX_ACTIVE_TOL, near_lo = ax <= L->lo[i] + LEX_ACTIVE_TOL;
    s[i] = near_lo ? LEX_LOWER : LEX_FREE;
    if (near_up && (!near_lo || L->up[i] - ax <= ax - L->lo[i])) s[i] = LEX_UPPER;
    if (L->lo[i] == L->up[i]) s[i] = LEX_FIXED;
  }
}

static double lex_norm(const double* a, int n) { return sqrt(lex_dot(a, a, n)); }

/* W's fixed rows (lo = up), of unit length, into out (row-major); their count. */
static int lex_fixed_rows(const vfdsl_lex* L, const int* s, double* out) {
  int i, q = 0;
  for (i=0;i<L->K;++i) if (s[i] == LEX_FIXED) lex_unit_row(L, i, out + LEX_N(L)*q++);
  return q;
}

/* The multipliers of gradient g by back-substitution through the steps of the levels above j (j .. 1) and then of
 * W's rows (step 0), each R11 mu = -Y'v (v: g plus the rows' part so far; 0 on a step's dependent rows). sigma: W's
 * multipliers (in W's order) unclipped into it; else W's inequality multipliers clipped to their sign. Returns
 * |g + sum_l R_l' mu_l + C_W' sigma| plus LEX_ROUNDING sum |mu_i| |row_i| (lexls.py's _rounding). */
static double lex_back_substitute(vfdsl_lex* L, int j, const double* g, double* sigma) {
  int n = LEX_N(L), st, i, l;
  double *v = L->res, *c = L->c, charge = 0;
  memcpy(v, g, sizeof(double) * n);
  if (sigma) for (i=0;i<L->p[0];++i) sigma[i] = 0;
  for (st=j; st>=0; --st) {
    int r = L->r[st];
    const int* piv = L->fpiv + L->fpiv_at[st];
    const double *R11 = L->fR + L->fR_at[st], *Y = L->Z + L->off[st]*n;
    for (i=0;i<r;++i) c[i] = -lex_dot(Y + i*n, v, n);
    for (i=r-1;i>=0;--i) {
      for (l=i+1;l<r;++l) c[i] -= R11[i + l*r]*c[l];
      c[i] /= R11[i + i*r];
    }
    for (i=0;i<r;++i) {
      const double* row = L->rows[st] + piv[i]*n;
      if (st == 0 && sigma) sigma[piv[i]] = c[i];
      else if (st == 0 && L->side[piv[i]] != LEX_FIXED && c[i]*L->side[piv[i]] < 0) continue;   /* clipped to 0 */
      for (l=0;l<n;++l) v[l] += c[i]*row[l];
      charge += LEX_ROUNDING * fabs(c[i]) * lex_norm(row, n);
    }
  }
  return lex_norm(v, n) + charge;
}

/* 1 when the solve's own factors certify level j (gradient g): multipliers by back-substitution through the steps of
 * the levels above (j .. 1) and then of W's rows (step 0), each R11 mu = -Y'v (v: g plus the rows' part so far; 0 on
 * a step's dependent rows), W's inequality multipliers clipped to their sign, and the whole residual
 * |g + sum_l R_l' mu_l + C_W' sigma| within thr: the KKT conditions of level j, so sufficient. (When a level above
 * is rank-deficient its multipliers are not unique, and this choice may miss: the general certificate decides.) */
static int lex_factors_dual(vfdsl_lex* L, int j, const double* g, double thr) {
  return lex_back_substitute(L, j, g, 0) <= thr;
}

/* 1 when the q rows S (row-major, n columns) are independent, each at least COND_TOL from the span of those before
 * it: the Cholesky of their Gram matrix S S' (in L->K2 when q <= n), every pivot above COND_TOL^2. */
static int lex_independent(vfdsl_lex* L, const double* S, int q, int n) {
  int i, j, l;
  double* G = L->K2;
  if (q > n) return 0;          /* more than n rows of length n are dependent */
  for (j=0;j<q;++j) {
    double d = lex_dot(S + j*n, S + j*n, n), inv;
    for (l=0;l<j;++l) d -= G[j + l*q]*G[j + l*q];
    if (!(d > LEX_COND_TOL*LEX_COND_TOL)) return 0;
    inv = 1 / sqrt(d);
    for (i=j+1;i<q;++i) {
      double v = lex_dot(S + i*n, S + j*n, n);
      for (l=0;l<j;++l) v -= G[i + l*q]*G[j + l*q];
      G[i + j*q] = v * inv;
    }
  }
  return 1;
}

/* 1 when level j is certified by dimensions: the null space V of the fixed rows and the levels above contains the
 * solve's null space after those levels (Z_j, where W's rows are held too), of dimension n - after, so V = Z_j when
 * those rows are `after` independent ones; then g's part in V is Z_j'g, 0 by the solve's optimality (checked within
 * thr), and W's rows need no multipliers. */
static int lex_dims_dual(vfdsl_lex* L, const vfdsl_lex_prob* P, const int* s, int fixed, int j, const double* g,
                         double thr) {
  int n = LEX_N(P), after = L->off[j] + L->r[j], levels = L->level_at[j], i;
  const double *Z = L->Z + after*n, *above = L->LR;   /* the rows of the levels above j */
  double norm2 = 0;
  if (fixed + levels != after) return 0;     /* (then rank < after, or a search) */
  if (fixed) {                  /* the fixed rows, then the levels' (else those, where they are) */
    lex_fixed_rows(L, s, L->B);
    memcpy(L->B + n*fixed, above, sizeof(double) * n * levels);
    above = L->B;
  }
  if (!lex_independent(L, above, after, n)) return 0;
  for (i=0;i<n-after;++i) { double d = lex_dot(Z + i*n, g, n); norm2 += d*d; }
  return sqrt(norm2) <= thr;
}

/* Level j's gradient at x into g (the last cost's for j = L->levels), and its scale (lexls.py's _certified). */
static double lex_gradient(const vfdsl_lex* L, const vfdsl_lex_prob* P, int j, const double* x, double* g) {
  int n = LEX_N(P), i, l;
  double xn = lex_norm(x, n);
  if (j < L->levels) {
    const double *R = L->LR + L->level_at[j]*n, *r = L->lt + L->level_at[j];
    double rn = 0, Rn = 0;
    int rows = L->level_rows[j];
    for (i=0;i<n;++i) g[i] = 0;
    for (i=0;i<rows;++i) {
      double e = lex_dot(R + i*n, x, n) - r[i];
      for (l=0;l<n;++l) g[l] += R[i*n + l]*e;
      rn += r[i]*r[i];
      Rn += lex_dot(R + i*n, R + i*n, n);
    }
    return sqrt(Rn) * (sqrt(Rn) * xn + sqrt(rn));
  } else {
    double Hn = 0;
    for (i=0;i<n;++i) {
      g[i] = P->f[i];
      for (l=0;l<n;++l) { g[i] += P->H[i + l*n]*x[l]; Hn += P->H[i + l*n]*P->H[i + l*n]; }
    }
    return sqrt(Hn) * xn + lex_norm(P->f, n);
  }
}

/* The held inequality row to drop when level j is refused (lexls.py's _drop), or -1: W's multipliers of each level
 * lv <= j by back-substitution; among the rows no level above j holds back and not pinned (vfdsl_lex_from's), the
 * one most negative at j. */
static int lex_drop(vfdsl_lex* L, const vfdsl_lex_prob* P, const int* s, const double* x, int j) {
  int i, w, lv, best = -1, *locked = L->cols;
  double *sigma = L->w, least = 0;
  if (L->steps <= j) return -1;
  for (w=0;w<L->p[0];++w) locked[w] = 0;
  for (lv=0; lv<=j; ++lv) {
    double thr = LEX_DUAL_TOL * lex_gradient(L, P, lv, x, L->g);
    lex_back_substitute(L, lv, L->g, sigma);
    for (i=0, w=0; i<P->K; ++i) if (s[i] != LEX_FREE) {       /* (W's rows are the held ones, in order) */
      int side = s[i] == LEX_FIXED || L->pinned[i] ? 0 : s[i];
      double signed_sigma = sigma[w] * side;
      if (lv < j) { if (signed_sigma > thr) locked[w] = 1; }
      else if (side && !locked[w] && signed_sigma < -thr && (best < 0 || signed_sigma < least)) {
        least = signed_sigma;
        best = i;
      }
      ++w;
    }
  }
  return best;
}

/* 1 when x (n) is certified (vfdsl.runtime.lexls._certified): per level, by the solve's factors or by dimensions
 * when they do, else by the nonnegative least squares over the null space U of the fixed rows and the levels above
 * (that chain built only when a level needs it). Refused by the NNLS: L->hint the row to drop (lex_drop). */
static int lex_certified(vfdsl_lex* L, const vfdsl_lex_prob* P, const int* s, const double* x) {
  int n = LEX_N(P), i, j, l, a = 0, fixed = 0, k = n, ident = 1, chained = -1;
  double *U = L->U, *N = L->N, *g = L->g, *b = L->y;
  for (i=0;i<P->K;++i) {
    a += s[i] == LEX_UPPER || s[i] == LEX_LOWER;
    fixed += s[i] == LEX_FIXED;
  }
  if (a == 0) return 1;         /* the chain of null spaces is the primal one: optimal in it by construction */
  for (j=0;j<=L->levels;++j) {     /* the levels (vfdsl_lex_rows), then the last cost (j = L->levels) */
    double thr = LEX_DUAL_TOL * lex_gradient(L, P, j, x, g);
    if (L->steps > j && (lex_dims_dual(L, P, s, fixed, j, g, thr) || lex_factors_dual(L, j, g, thr))) continue;
    if (chained < 0) {           /* U: the null space of the fixed rows */
      lex_fixed_rows(L, s, L->T);
      memset(U, 0, sizeof(double) * n * n);
      for (i=0;i<n;++i) U[i + i*n] = 1;
      if (lex_step(L, L->T, fixed, 0, 0, &U, &k, &ident, -1) < 0) return 0;
      chained = 0;
    }
    for (; chained<j; ++chained) {  /* ... and of the levels above */
      if (lex_step(L, L->LR + L->level_at[chained]*n, L->level_rows[chained], 0, 0, &U, &k, &ident, -1) < 0)
        return 0;
    }
    if (k == 0) return 1;        /* nothing left free: every level below is met */
    a = 0;
    if (ident) {                 /* U = I */
      for (l=0;l<k;++l) b[l] = -g[l];
      for (i=0;i<P->K;++i) if (s[i] == LEX_UPPER || s[i] == LEX_LOWER) {
        for (l=0;l<k;++l) N[l + a*k] = s[i] * L->A[i*n + l];      /* (any positive column scale: same minimum) */
        ++a;
      }
    } else {
      for (l=0;l<k;++l) b[l] = -lex_dot(U + l*n, g, n);
      for (i=0;i<P->K;++i) if (s[i] == LEX_UPPER || s[i] == LEX_LOWER) {
        for (l=0;l<k;++l) N[l + a*k] = s[i] * lex_dot(U + l*n, L->A + i*n, n);
        ++a;
      }
    }
    if (a ? !lex_nnls_within(L, N, k, a, b, thr) : lex_norm(b, k) > thr) {
      L->hint = -1;
      L->hint_side = LEX_FREE;
      if (L->from) {                      /* vfdsl_lex_from's drop */
        if (a) L->hint = lex_drop(L, P, s, x, j);
      } else if (a && L->hint_column >= 0) {   /* a repair's: the held inequality row of that NNLS column */
        int column = 0;
        for (i=0;i<P->K;++i) if (s[i] == LEX_UPPER || s[i] == LEX_LOWER) {
          if (column++ == L->hint_column) { L->hint = i; break; }
        }
      }
      return 0;
    }
  }
  return 1;
}

/* The refused working set s changed by the last solve's hint; 0 when there was none. */
int vfdsl_lex_repair(vfdsl_lex* L, int* s) {
  if (L->hint < 0 || s[L->hint] == LEX_FIXED) return 0;
  s[L->hint] = L->hint_side;
  return 1;
}

/* The levels' optimum over the working set s into x; 1 when certified (lexls.py's _solve_over). W's rows nearly
 * dependent: L->ill_at >= 0 after it, L->piv their pivot order; ill_ok: W's pivots only above RANK_TOL (2: the
 * levels' too). Refused with x computed: L->hint >= 0 (a row violated, or one to drop). */
static int lex_solve_over(vfdsl_lex* L, const vfdsl_lex_prob* P, const int* s, double* x, int ill_ok) {
  int n = LEX_N(P), i, j, l, p = 0, k = n, ident = 1, record = L->levels + 1 <= L->max_steps;
  double *Z = L->Z;
  L->hint = -1;
  L->ill_at = -1;
  L->ill_ok = 0;
  L->steps = 0;
  for (i=0;i<P->K;++i) if (s[i] != LEX_FREE) {
    L->side[p] = s[i];
    lex_unit_row(L, i, L->M + p*n);
    L->t[p] = s[i] == LEX_LOWER ? L->lo[i] : L->up[i];
    if (!isfinite(L->t[p++])) return 0;     /* a row held at an infinite bound */
  }
  memset(x, 0, sizeof(double) * n);
  memset(Z, 0, sizeof(double) * n * n);
  for (i=0;i<n;++i) Z[i + i*n] = 1;
  L->ill_ok = ill_ok;              /* (W's step; with 2 the levels' too) */
  if (lex_step(L, L->M, p, L->t, x, &Z, &k, &ident, record ? 0 : -1) < 0) return 0;
  L->ill_ok = ill_ok == 2;
  L->ill_at = -1;                  /* (only W's step reports it) */
  for (i=0;i<p;++i) if (fabs(lex_dot(L->M + i*n, x, n) - L->t[i]) > LEX_PRIMAL_TOL) return 0;
  for (j=0;j<L->levels;++j) {
    if (lex_step(L, L->LR + L->level_at[j]*n, L->level_rows[j], L->lt + L->level_at[j], x, &Z, &k, &ident,
                 record ? j + 1 : -1) < 0)
      return 0;
  }
  if (k) {       /* y = -(Z'HZ)^-1 Z'(Hx + f) */
    double *g = L->g, *y = L->y, *HZ = L->K2;
    for (i=0;i<n;++i) { g[i] = P->f[i]; for (l=0;l<n;++l) g[i] += P->H[i + l*n]*x[l]; }
    for (l=0;l<k;++l) y[l] = -lex_dot(Z + l*n, g, n);
    for (j=0;j<k;++j) {          /* Z'HZ into HZ (k x k), H symmetric */
      for (i=0;i<n;++i) { double s2 = 0; for (l=0;l<n;++l) s2 += P->H[i + l*n]*Z[l + j*n]; g[i] = s2; }
      for (l=0;l<k;++l) HZ[l + j*k] = lex_dot(Z + l*n, g, n);
    }
    if (lex_cholesky_solve(HZ, k, y) < 0) return 0;
    for (l=0;l<k;++l) for (i=0;i<n;++i) x[i] += Z[i + l*n]*y[l];
  }
  for (i=0;i<n;++i) if (!isfinite(x[i])) return 0;
  {
    double worst = LEX_PRIMAL_TOL;
    for (i=0;i<P->K;++i) {
      double ax = lex_dot(L->A + i*n, x, n)*L->inv[i];
      if (L->lo[i] - ax > worst) { worst = L->lo[i] - ax; L->hint = i; L->hint_side = LEX_LOWER; }
      if (ax - L->up[i] > worst) { worst = ax - L->up[i]; L->hint = i; L->hint_side = LEX_UPPER; }
    }
    if (L->hint >= 0) return 0;        /* the most violated row: add it */
  }
  L->ill_ok = 0;
  return lex_certified(L, P, s, x);
}

/* The levels' optimum over s into x; 1 when certified (lexls.py's solve_over). When W's rows are nearly dependent
 * (a degenerate vertex: lexls.py's _degenerate), s without one of them (those in pivot order up to the nearly
 * dependent one), the last hard row first and LEX_DEGENERATE_DROPS of them at most, then s as it is with W's pivots
 * only above RANK_TOL; s becomes the
 * working set certified. */
int vfdsl_lex_solve(vfdsl_lex* L, const vfdsl_lex_prob* P, int* s, double* x) {
  int count, k, i, held, tried = 0;
  if (lex_solve_over(L, P, s, x, 0)) return 1;
  if (L->ill_at < 0) return 0;
  count = L->ill_at + 1;
  for (i=0;i<P->K;++i) L->drop[i] = 0;
  for (k=0;k<count;++k) L->drop[L->piv[k]] = 1;     /* W's rows, by their place among the held, to try without */
  for (i=P->K-1, held=0; i>=0; --i) held += s[i] != LEX_FREE;
  for (i=P->K-1; i>=0; --i) {
    if (s[i] == LEX_FREE || !L->drop[--held] || s[i] == LEX_FIXED) continue;
    if (tried++ == LEX_DEGENERATE_DROPS) break;
    memcpy(L->trial, s, sizeof(int) * P->K);
    L->trial[i] = LEX_FREE;
    if (lex_solve_over(L, P, L->trial, x, 0)) {
      s[i] = LEX_FREE;
      return 1;
    }
  }
  if (lex_solve_over(L, P, s, x, 1)) return 1;
  L->hint = -1;
  return 0;
}

/* The working set of x with each inequality row left out that lies within COND_TOL of the span of the held rows
 * before it, the fixed rows first, then those x leaves by more than PRIMAL_TOL, then the others, each by index
 * (lexls.py's _independent_working_set; L->B holds that span's orthonormal basis, L->c the row's coordinates in
 * it). */
static void lex_independent_working_set(vfdsl_lex* L, const double* x, int* s) {
  int n = LEX_N(L), pass, i, l, j, q = 0;
  double *basis = L->B, *rest = L->g, *w = L->c;
  vfdsl_lex_working_set(L, x, s);
  for (pass=0; pass<3; ++pass) for (i=0;i<L->K;++i) {
    double norm, ax;
    int off;
    if (pass == 0 ? s[i] != LEX_FIXED : (s[i] != LEX_UPPER && s[i] != LEX_LOWER)) continue;
    ax = lex_dot(L->A + i*n, x, n)*L->inv[i];
    off = ax < L->lo[i] - LEX_PRIMAL_TOL || ax > L->up[i] + LEX_PRIMAL_TOL;
    if ((pass == 1 && !off) || (pass == 2 && off)) continue;
    lex_unit_row(L, i, rest);
    for (l=0;l<q;++l) w[l] = lex_dot(basis + l*n, rest, n);
    for (l=0;l<q;++l) for (j=0;j<n;++j) rest[j] -= w[l]*basis[l*n + j];
    norm = lex_norm(rest, n);
    if (norm > LEX_COND_TOL && q < n) {
      for (j=0;j<n;++j) basis[q*n + j] = rest[j] / norm;
      ++q;
    } else if (s[i] != LEX_FIXED) {
      s[i] = LEX_FREE;
    }
  }
}

/* The first free hard row met on the way from x to y (the smallest step alpha in [0, 1), the first row among
 * equals), its side in *side and alpha in *alpha; -1 when none (lexls.py's _first_blocking). */
static int lex_first_blocking(const vfdsl_lex* L, const int* s, const double* x, const double* y, double* d,
                              int* side, double* alpha) {
  int n = LEX_N(L), i, j, best = -1;
  double moving;
  for (j=0;j<n;++j) d[j] = y[j] - x[j];
  moving = LEX_RANK_TOL * lex_norm(d, n);
  for (i=0;i<L->K;++i) {
    double ad, ax, a;
    int at;
    if (s[i] != LEX_FREE) continue;
    ad = lex_dot(L->A + i*n, d, n)*L->inv[i];
    ax = lex_dot(L->A + i*n, x, n)*L->inv[i];
    if (ad > moving && isfinite(L->up[i])) { a = (L->up[i] - ax) / ad; at = LEX_UPPER; }
    else if (ad < -moving && isfinite(L->lo[i])) { a = (L->lo[i] - ax) / ad; at = LEX_LOWER; }
    else continue;
    if (a < 0) a = 0;
    if (a < 1 && (best < 0 || a < *alpha)) { best = i; *side = at; *alpha = a; }
  }
  return best;
}

/* From x, a point of the hard rows, to the levels' optimum (lexls.py's from_feasible): W the independent rows x
 * holds; solve over W (y); when y leaves a hard row, step toward it up to the first row that blocks and hold that
 * row; else move to y, certified or the row the certificate names dropped. x: the last iterate, s its working set
 * (K entries); 1 when certified.
 * At most LEX_PRIMAL_STEPS iterations. */
int vfdsl_lex_from(vfdsl_lex* L, const vfdsl_lex_prob* P, int* s, double* x) {
  int n = LEX_N(P), iteration, j, dropped = -1, certified = 0;
  double *y = L->from_y, *d = L->from_d;
  lex_independent_working_set(L, x, s);
  L->from = 1;
  for (iteration=0; iteration<LEX_PRIMAL_STEPS; ++iteration) {
    if (lex_solve_over(L, P, s, y, 2)) {
      memcpy(x, y, sizeof(double) * n);
      certified = 1;
      break;
    }
    if (L->hint < 0) break;                  /* no answer over s, or a refusal without a row to drop */
    if (L->hint_side != LEX_FREE) {          /* y leaves a hard row: up to the first that blocks, held from there */
      int side = 0;
      double alpha = 1;
      int i = lex_first_blocking(L, s, x, y, d, &side, &alpha);
      if (i < 0) break;
      if (i == dropped && alpha == 0) L->pinned[i] = 1;    /* blocking at once after its drop: kept from now on */
      for (j=0;j<n;++j) x[j] += alpha * d[j];
      s[i] = side;
    } else {                                 /* at y, the row the certificate names is dropped */
      memcpy(x, y, sizeof(double) * n);
      dropped = L->hint;
      s[dropped] = LEX_FREE;
    }
  }
  memset(L->pinned, 0, sizeof(int) * L->K);  /* (no pinned row outside this method) */
  L->from = 0;
  return certified;
}
