/* vfdsl: priority levels solved exactly over a working set, with a certificate of optimality (lexls.c).
 *
 * The C of vfdsl/runtime/lexls.py (whose docstring holds the math), step for step with the same tolerances, for
 * the generated tick: its own Householder QR (with column pivoting for the ranks), Cholesky and Lawson-Hanson
 * nonnegative least squares, on the dense data of DAQP's problem (daqp_persistent.c):
 *
 *   hard rows   DAQP's general rows [0, K), bounds blower/bupper[ms + i] (unit length here, scaled per tick)
 *   level j     DAQP's rows [b_j - ms, b_{j+1} - ms), targets blower (= bupper), b the break points; a row that
 *               is zero with a zero target (a term of weight 0) is left out, and a level left empty (lexls.py's
 *               split does the same)
 *   last cost   1/2 x'Hx + f'x
 *
 * vfdsl_lex_solve(lex, prob, s, x) computes the levels' optimum with the working set s (LEX_UPPER, LEX_LOWER,
 * LEX_FIXED held as equalities, LEX_FREE left out) and returns 1 when it is certified as the optimum of the whole
 * problem, 0 otherwise (x then undefined; L->hint names a row whose change may fix the working set: the most
 * violated row, or the held row with the most negative least-squares multiplier of the NNLS that refused; within
 * vfdsl_lex_from, the held row of lexls.py's _drop rule). When s's rows are nearly dependent (a
 * degenerate vertex), s without one of them is tried, then s with its pivots only above RANK_TOL, and s becomes the
 * working set that was certified. vfdsl_lex_repair(lex, s) applies the hint to s
 * (1 when there was one). vfdsl_lex_from(lex, prob, s, x) goes from x, a point of the hard rows, to the levels'
 * optimum by a primal active-set method (lexls.py's from_feasible), x its last iterate and s its working set, 1 when
 * certified. The certificate tries, per level, the multipliers from the solve's own factors and a
 * test by dimensions before its nonnegative least squares (as lexls.py). All memory is one block, allocated once by
 * vfdsl_lex_alloc and released by vfdsl_lex_free.
 */
#ifndef VFDSL_LEXLS_H
#define VFDSL_LEXLS_H

/* lexls.c is compiled once per number of variables n (-DVFDSL_LEX_N=n), into a static library beside DAQP's
   (vfdsl.codegen.build.lexls_library; an export ships it as generated/lexls.c, its Makefile and CMakeLists.txt
   define the task's n); this header is put at the top of daqp_persistent.c in every generated file. */
enum { LEX_FREE = 0, LEX_UPPER = 1, LEX_LOWER = -1, LEX_FIXED = 2 };

typedef struct vfdsl_lex {
  int n, K;               /* variables, hard rows */
  int valid;              /* guess holds a working set */
  int hint_column;        /* a repair's hint: the NNLS column with the most negative least-squares multiplier */
  int from;               /* in vfdsl_lex_from: a refusal's hint is lex_drop's (lexls.py's _drop) */
  int hint, hint_side;    /* after a refusal: a hard row to add at side hint_side (+1, -1), or to drop (0); -1: none */
  int ill_at;             /* lex_qr's first pivot in (RANK_TOL, COND_TOL] of the last ill-conditioned step, or -1 */
  int ill_ok;             /* the step being made may have such pivots (W's, as the last resort at a degenerate vertex;
                             the levels' too in vfdsl_lex_from) */
  int *guess, *piv, *cols;
  int *drop, *trial;      /* a degenerate working set: its rows to try without, and the working set tried */
  int *pinned;            /* vfdsl_lex_from's rows not to drop (all 0 outside it) */
  const double* A;        /* the hard rows (K x n, row-major: DAQP's), set by vfdsl_lex_rows */
  double *inv, *lo, *up;  /* 1 / each hard row's length, and its bounds over that length (the unit row's) */
  int levels;             /* the levels with a row that is not zero or has a target that is not (vfdsl_lex_rows): */
  int *level_at, *level_rows;   /* their rows at LR + level_at[j] n (row-major), targets at lt + level_at[j] */
  double *LR, *lt;
  double *M, *t;          /* gathered rows (row-major) and targets */
  double *B, *T, *tau, *tau2, *c;
  double *Z, *U, *x, *g, *y, *K2;
  double *from_y, *from_d; /* vfdsl_lex_from's: the optimum over its working set, and the step toward it */
  double *N, *NP, *lam, *sol, *w, *res;
  /* the solve's factors, for the certificate: step 0 holds W's rows, step l >= 1 level l - 1; Z keeps its whole
     basis [Y_0 | Y_1 | ... | null space], Y_l = columns [off[l], off[l] + r[l]) of Z */
  int steps, max_steps, *off, *r, *p, *fpiv, *fpiv_at, *fR_at, *side;   /* side: W's rows' s, in their order */
  const double** rows;    /* each step's rows (row-major, p[l] of them) */
  double* fR;             /* each step's R11 (r x r, column-major, upper triangular), at fR_at[l] */
} vfdsl_lex;

/* The problem, as DAQP holds it. */
typedef struct {
  int n, ms, K, nh;
  const int* break_points;
  const double *H, *f, *A, *blower, *bupper;
} vfdsl_lex_prob;

vfdsl_lex* vfdsl_lex_alloc(int n, int K, int P);
void vfdsl_lex_free(vfdsl_lex* L);
void vfdsl_lex_rows(vfdsl_lex* L, const vfdsl_lex_prob* P);
void vfdsl_lex_working_set(const vfdsl_lex* L, const double* x, int* s);
int vfdsl_lex_solve(vfdsl_lex* L, const vfdsl_lex_prob* P, int* s, double* x);
int vfdsl_lex_repair(vfdsl_lex* L, int* s);
int vfdsl_lex_from(vfdsl_lex* L, const vfdsl_lex_prob* P, int* s, double* x);

#endif
