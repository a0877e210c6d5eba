/* vfdsl: DAQP (the daqp package's C sources) with a persistent, warm-started workspace, and priority levels.
 *
 * Replaces CasADi's casadi_daqp_free_mem and casadi_daqp_solve in a generated file (see patch.py).
 * CasADi's solve calls setup_daqp (malloc, Cholesky) and frees the workspace on every call, and
 * starts DAQP from the equality rows alone. vfdsl_daqp_solve(d, warm, levels) is called instead: patch.py
 * passes warm = 1 for the conics whose SolvePlan says so, and for a conic with priority levels the
 * constraint indices where each level ends (DAQP's break points), else levels = 0:
 *   - sets DAQP up on a conic's first call and keeps the workspace in the conic's static memory
 *     (d->work) until casadi_daqp_free_mem: later calls allocate nothing;
 *   - refreshes the problem in place (daqp_update_ldp: factor of H, M = A R^-1, v, d), the sizes being
 *     fixed by the conic's sparsity;
 *   - warm: start DAQP from the previous solve's working set when that solve succeeded (DAQP drops the
 *     constraints of that set that are dependent for the new data);
 *   - levels: DAQP's hierarchical mode. Level 0 (the box and the rows) is hard; level k >= 1 minimizes
 *     the squared violations of its rows, in the rows' own units (each row's soft weight is the conic's rho
 *     in the scale of the problem, which undoes DAQP's normalization of the rows), keeping every level above
 *     at its optimum; the QP's own cost acts last;
 *   - from a point (phase 2's (B)): the levels solved from the conic's x0 by lexls.c's primal active-set method,
 *     the answer when certified, else x0 (DAQP is not called);
 *   - exact levels (lexls.c): first the levels solved exactly over the previous tick's working set, taken
 *     when certified (DAQP is then not called), the guess repaired up to VFDSL_REPAIRS times (add the most
 *     violated row, or drop the held row with the most negative multiplier); else DAQP's answer, solved again
 *     exactly over the rows it holds, then, where that is not certified, taken from there to the optimum by
 *     lexls.c's primal active-set method: the result when certified (the interpreted path does the same with
 *     vfdsl.runtime.lexls.polish), else DAQP's answer as is;
 *   - reports a failed solve as x = NaN, never as a stale or internal iterate.
 */
#include <daqp/types.h>
#include <daqp/constants.h>
#include <daqp/utils.h>        /* daqp_update_ldp (api.h does not declare the update functions) */

#define VFDSL_LEVELS_MAX 16
#define VFDSL_REPAIRS 2    /* changes of one row to a refused guess (lexls.c's hint) before DAQP is called */
/* A conic's levels (from its SolvePlan): DAQP's break points, rho (the soft rows' reciprocal weight), partial: a
   failed level gives the answer of the levels above it (which meets the hard level) rather than NaN, and exact:
   the levels' rows are targets (lower = upper), so lexls.c may solve them exactly (see vfdsl_daqp_solve); start:
   the levels solved from the conic's x0, a point of the hard rows, by lexls.c's primal active-set method alone. */
typedef struct { int nh; double rho; int partial; int exact; int start; int break_points[VFDSL_LEVELS_MAX]; }
  vfdsl_levels;

static void vfdsl_daqp_cold_sense(const struct casadi_qp_prob* p_qp, const struct casadi_qp_data* d_qp,
                                  int* sense) {
  casadi_int i;
  for (i=0;i<p_qp->nx;++i) sense[i] = d_qp->lbx[i]==d_qp->ubx[i] ? DAQP_ACTIVE+DAQP_IMMUTABLE : 0;
  for (i=0;i<p_qp->na;++i) sense[p_qp->nx+i] = d_qp->lba[i]==d_qp->uba[i] ? DAQP_ACTIVE+DAQP_IMMUTABLE : 0;
}

/* The conic's matrix x (sparsity sp) into the dense y, row-major when tr: a plain loop when x is dense (it is for
   every vfdsl conic), CasADi's sparse densify otherwise (that one, with its index loads, took ~15 % of
   experiment B's step() for the 40 x 7 rows, measured with perf); transposed column by column, loads in order (row
   by row, the strided loads took 0.1 us of B's 2.1 us tick in a C loop: 2.08 -> 2.04 us) */
static void vfdsl_dense(const casadi_real* x, const casadi_int* sp, casadi_real* y, int tr) {
  casadi_int rows = sp[0], cols = sp[1], i, j;
  if (sp[2 + cols] != rows * cols) {
    casadi_densify(x, sp, y, tr);
  } else if (!tr) {
    casadi_copy(x, rows * cols, y);
  } else {
    for (j=0;j<cols;++j) for (i=0;i<rows;++i) y[i*cols + j] = x[i + j*rows];
  }
}

static void vfdsl_fill_nan(casadi_real* x, casadi_int n) {
  casadi_int i;
  if (x) for (i=0;i<n;++i) x[i] = NAN;
}

/* Optimal; with levels, every level optimal (SOFT_OPTIMAL, DAQP's normal answer); not CONSTRAINED_POINT, the
   answer of the levels above a level DAQP failed to solve (vfdsl.runtime.qp retries such a solve). */
static int vfdsl_daqp_succeeded(int flag) {
  return flag==DAQP_EXIT_OPTIMAL || flag==DAQP_EXIT_SOFT_OPTIMAL;
}

/* First call: DAQP's workspace, its hierarchy and the soft weights of the levels' rows (all its memory). */
static int vfdsl_daqp_setup(struct casadi_daqp_data* d, const vfdsl_levels* levels) {
  int i, flag;
  DAQPWorkspace* work = &d->work;
  flag = setup_daqp(&d->daqp, work, 0);
  if (flag<0 || !levels) return flag;
  if (!daqp_allocate_soft_weights(work)) return DAQP_EXIT_UNSUPPORTED;
  for (i=levels->break_points[0];i<d->daqp.m;++i) work->rho_ls[i] = work->rho_us[i] = levels->rho;
  return flag;
}

static int vfdsl_daqp_update(struct casadi_daqp_data* d, int warm) {
  casadi_int i;
  int* sense = d->daqp.sense;
  DAQPWorkspace* work = &d->work;
  if (warm && vfdsl_daqp_succeeded(d->return_status)) {
    for (i=0;i<d->daqp.m;++i) if (!sense[i]) sense[i] = work->sense[i] & (DAQP_ACTIVE+DAQP_LOWER);
  }
  return daqp_update_ldp(DAQP_UPDATE_Rinv+DAQP_UPDATE_M+DAQP_UPDATE_v+DAQP_UPDATE_d+DAQP_UPDATE_sense,
                         work, &d->daqp);
}

void casadi_daqp_free_mem(struct casadi_daqp_data* d) {
  vfdsl_lex_free(d->lex);
  d->lex = 0;
  d->work.settings = 0;  /* the settings belong to the caller's frame, not to DAQP */
  free_daqp_workspace(&d->work);
  free_daqp_ldp(&d->work);
  d->return_status = 0;
}

/* The problem as DAQP holds it (its data filled in), for lexls.c. */
static void vfdsl_lex_prob_of(const struct casadi_daqp_data* d, const vfdsl_levels* levels, vfdsl_lex_prob* prob) {
  prob->n = d->daqp.n;
  prob->ms = d->daqp.ms;
  prob->K = levels->break_points[0] - d->daqp.ms;
  prob->nh = levels->nh;
  prob->break_points = levels->break_points;
  prob->H = d->daqp.H;
  prob->f = d->daqp.f;
  prob->A = d->daqp.A;
  prob->blower = d->daqp.blower;
  prob->bupper = d->daqp.bupper;
}

/* lexls.c's problem (prob) and workspace (d->lex, allocated on the first call) for this call's data, its rows read;
   NULL when it cannot be allocated (out of memory, or compiled for another n). */
static vfdsl_lex* vfdsl_lex_ready(struct casadi_daqp_data* d, const vfdsl_levels* levels, vfdsl_lex_prob* prob) {
  vfdsl_lex_prob_of(d, levels, prob);
  if (!d->lex) d->lex = vfdsl_lex_alloc(prob->n, prob->K, d->daqp.m - levels->break_points[0]);
  if (d->lex) vfdsl_lex_rows(d->lex, prob);
  return d->lex;
}

/* x (in d->qp->x) is the levels' answer: a success, without multipliers. The conic's cost output carries the
   certificate instead of a cost (vfdsl.runtime.daqp_solve): 0 where x is the certified optimum, 1 where it is not
   (the x0 of a start plan kept). */
static void vfdsl_exact_answer(struct casadi_daqp_data* d, int certified) {
  struct casadi_qp_data* d_qp = d->qp;
  const struct casadi_qp_prob* p_qp = d->prob->qp;
  casadi_int i;
  d->return_status = DAQP_EXIT_OPTIMAL;
  d->nodecount = 0;
  d->bnb_itercount = 0;
  d->lex->valid = 1;
  d_qp->success = 1;
  if (d_qp->lam_x) for (i=0;i<p_qp->nx;++i) d_qp->lam_x[i] = 0;
  if (d_qp->lam_a) for (i=0;i<p_qp->na;++i) d_qp->lam_a[i] = 0;
  if (d_qp->f) *d_qp->f = !certified;
}

static int vfdsl_daqp_solve(struct casadi_daqp_data* d, int warm, const vfdsl_levels* levels) {
  int flag;
  vfdsl_lex_prob prob;
  const struct casadi_daqp_prob* p = d->prob;
  const struct casadi_qp_prob* p_qp = p->qp;
  struct casadi_qp_data* d_qp = d->qp;
  DAQPSettings* settings = (DAQPSettings*) (&p->settings);
  settings->eq_reduction = DAQP_EQ_REDUCTION_OFF;   /* the same LDP every tick: no reduced copy */
  settings->iter_limit = @ITER_LIMIT@;               /* a bounded solve (vfdsl.codegen.solve_plan.ITER_LIMIT) */
  vfdsl_daqp_cold_sense(p_qp, d_qp, d->daqp.sense);
  d->daqp.n = p_qp->nx;
  d->daqp.m = p_qp->nx + p_qp->na;
  d->daqp.ms = p_qp->nx;
  d->daqp.problem_type = 0;
  d->daqp.nh = levels ? levels->nh : 0;
  d->daqp.break_points = levels ? (int*) levels->break_points : 0;
  d->work.settings = settings;
  d->res.x = d_qp->x;
  vfdsl_dense(d->qp->h, d->prob->qp->sp_h, d->daqp.H, 0);
  vfdsl_dense(d->qp->a, d->prob->qp->sp_a, d->daqp.A, 1);
  casadi_copy(d_qp->lbx, p_qp->nx, d->daqp.blower);
  casadi_copy(d_qp->lba, p_qp->na, d->daqp.blower+p_qp->nx);
  casadi_copy(d_qp->ubx, p_qp->nx, d->daqp.bupper);
  casadi_copy(d_qp->uba, p_qp->na, d->daqp.bupper+p_qp->nx);
  d->daqp.f = (casadi_real*) (d_qp->g);
  if (levels && levels->start) {     /* from x0 (phase 2's (B)): the certified optimum, else x0; DAQP not called */
    if (vfdsl_lex_ready(d, levels, &prob) && d_qp->x0) {
      int certified;
      casadi_copy(d_qp->x0, p_qp->nx, d_qp->x);
      certified = vfdsl_lex_from(d->lex, &prob, d->lex->guess, d_qp->x);
      if (!certified) casadi_copy(d_qp->x0, p_qp->nx, d_qp->x);
      vfdsl_exact_answer(d, certified);
    } else {
      d->return_status = DAQP_EXIT_UNSUPPORTED;
      d_qp->success = 0;
      vfdsl_fill_nan(d_qp->x, p_qp->nx);
      if (d_qp->f) *d_qp->f = NAN;
    }
    return 0;
  }
  if (levels && levels->exact) {
    if (vfdsl_lex_ready(d, levels, &prob)) {
      int repair;
      for (repair=0; d->lex->valid; ++repair) {
        if (vfdsl_lex_solve(d->lex, &prob, d->lex->guess, d_qp->x)) {
          vfdsl_exact_answer(d, 1);
          return 0;
        }
        if (repair == VFDSL_REPAIRS || !vfdsl_lex_repair(d->lex, d->lex->guess)) break;
      }
    }
  }
  if (d->work.sense) {
    flag = vfdsl_daqp_update(d, warm);
  } else {
    flag = vfdsl_daqp_setup(d, levels);
    if (flag<0) casadi_daqp_free_mem(d);  /* setup may leave part of it allocated */
  }
  if (flag>=0) {
    daqp_solve(&d->res, &d->work);
    flag = d->res.exitflag;
  }
  d->work.settings = 0;
  d->return_status = flag;
  d->nodecount = 0;
  d->bnb_itercount = 0;
  d_qp->success = vfdsl_daqp_succeeded(flag)
                  || (levels && levels->partial && flag==DAQP_EXIT_CONSTRAINED_POINT);
  if (d->lex && levels && levels->exact) {     /* the levels solved exactly over the rows DAQP's answer holds */
    vfdsl_lex* lex = d->lex;
    if (d_qp->success) vfdsl_lex_working_set(lex, d_qp->x, lex->guess);
    if (d_qp->success && vfdsl_lex_solve(lex, &prob, lex->guess, lex->x)) {
      casadi_copy(lex->x, p_qp->nx, d_qp->x);
      vfdsl_exact_answer(d, 1);  /* (the next tick tries this working set first) */
      return 0;
    }
    if (d_qp->success) {         /* from DAQP's answer by the primal active-set method (lexls.py's polish) */
      casadi_copy(d_qp->x, p_qp->nx, lex->x);
      if (vfdsl_lex_from(lex, &prob, lex->guess, lex->x)) {
        casadi_copy(lex->x, p_qp->nx, d_qp->x);
        vfdsl_exact_answer(d, 1);
        return 0;
      }
    }
    lex->valid = 0;              /* not certified (e.g. an ill-conditioned working set): the next tick goes to DAQP */
  }
  if (d_qp->success) {
    casadi_copy(d->res.lam, p_qp->nx, d_qp->lam_x);
    casadi_copy(d->res.lam+p_qp->nx, p_qp->na, d_qp->lam_a);
    if (d_qp->f) *d_qp->f = levels && levels->exact ? 1 : d->res.fval;   /* exact plans: not certified */
  } else {
    vfdsl_fill_nan(d_qp->x, p_qp->nx);
    vfdsl_fill_nan(d_qp->lam_x, p_qp->nx);
    vfdsl_fill_nan(d_qp->lam_a, p_qp->na);
    if (d_qp->f) *d_qp->f = NAN;
  }
  return 0;
}

int casadi_daqp_solve(struct casadi_daqp_data* d, const double** arg, double** res, casadi_int* iw, double* w) {
  return vfdsl_daqp_solve(d, 0, 0);
}
