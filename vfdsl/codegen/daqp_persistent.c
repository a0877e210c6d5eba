/* vfdsl: DAQP with a persistent, warm-started workspace.
 *
 * Replaces CasADi's casadi_daqp_free_mem and casadi_daqp_solve in a generated file (see build.py).
 * CasADi's solve calls setup_daqp (malloc, Cholesky) and frees the workspace on every call, and
 * starts DAQP from the equality rows alone. vfdsl_daqp_solve(d, warm) is called instead, with warm = 1
 * by the conics build.py marks as warm-started, warm = 0 (through casadi_daqp_solve) by the others:
 *   - sets DAQP up on a conic's first call and keeps the workspace in the conic's static memory
 *     (d->work) until casadi_daqp_free_mem: later calls allocate nothing;
 *   - refreshes the problem in place (update_ldp: Cholesky of H, M = A R^-1, v, d), the sizes being
 *     fixed by the conic's sparsity;
 *   - warm: start DAQP from the previous solve's working set when that solve was optimal; if that
 *     set is linearly dependent for the new data, start cold (equality rows only);
 *   - reports a failed solve as x = NaN, never as a stale or internal iterate.
 */
#include <daqp/utils.h>        /* update_ldp (DAQP's api.h does not declare the update functions) */
#include <daqp/auxiliary.h>    /* activate_constraints */
static void vfdsl_daqp_cold_sense(const struct casadi_qp_prob* p_qp, const struct casadi_qp_data* d_qp,
                                  int* sense) {
  casadi_int i;
  for (i=0;i<p_qp->nx;++i) sense[i] = d_qp->lbx[i]==d_qp->ubx[i] ? ACTIVE+IMMUTABLE : 0;
  for (i=0;i<p_qp->na;++i) sense[p_qp->nx+i] = d_qp->lba[i]==d_qp->uba[i] ? ACTIVE+IMMUTABLE : 0;
}

static void vfdsl_fill_nan(casadi_real* x, casadi_int n) {
  casadi_int i;
  if (x) for (i=0;i<n;++i) x[i] = NAN;
}

static int vfdsl_daqp_update(struct casadi_daqp_data* d, int warm) {
  casadi_int i;
  int flag;
  int* sense = d->daqp.sense;
  DAQPWorkspace* work = &d->work;
  if (warm && d->return_status == EXIT_OPTIMAL) {
    for (i=0;i<d->daqp.m;++i) if (!sense[i]) sense[i] = work->sense[i] & (ACTIVE+LOWER);
  }
  /* For a diagonal H, update_Rinv moves the factor's buffer from Rinv to RinvD (and back when H is
     not diagonal) but cannot run twice on a diagonal H: give the buffer back to Rinv, the state
     setup_daqp leaves before its own update_ldp. */
  if (work->RinvD && !work->Rinv) {
    work->Rinv = work->RinvD;
    work->RinvD = 0;
  }
  /* As in setup_daqp: the sense is copied first, then the factors (empties the working set). */
  flag = update_ldp(UPDATE_Rinv+UPDATE_M+UPDATE_v+UPDATE_d+UPDATE_sense, work);
  if (flag<0) return flag;
  flag = activate_constraints(work);
  if (flag!=EXIT_OVERDETERMINED_INITIAL) return flag;
  reset_daqp_workspace(work);  /* the previous working set is dependent now: start cold */
  for (i=0;i<d->daqp.m;++i) if (!(work->sense[i] & IMMUTABLE)) work->sense[i] &= ~ACTIVE;
  return activate_constraints(work);
}

void casadi_daqp_free_mem(struct casadi_daqp_data* d) {
  d->work.settings = 0;  /* the settings belong to the caller's frame, not to DAQP */
  free_daqp_workspace(&d->work);
  free_daqp_ldp(&d->work);
  d->return_status = 0;
}

static int vfdsl_daqp_solve(struct casadi_daqp_data* d, int warm) {
  int flag;
  const struct casadi_daqp_prob* p = d->prob;
  const struct casadi_qp_prob* p_qp = p->qp;
  struct casadi_qp_data* d_qp = d->qp;
  vfdsl_daqp_cold_sense(p_qp, d_qp, d->daqp.sense);
  d->daqp.n = p_qp->nx;
  d->daqp.m = p_qp->nx + p_qp->na;
  d->daqp.ms = p_qp->nx;
  d->work.settings = (DAQPSettings*) (&p->settings);
  d->res.x = d_qp->x;
  casadi_densify(d->qp->h, d->prob->qp->sp_h, d->daqp.H, 0);
  casadi_densify(d->qp->a, d->prob->qp->sp_a, d->daqp.A, 1);
  casadi_copy(d_qp->lbx, p_qp->nx, d->daqp.blower);
  casadi_copy(d_qp->lba, p_qp->na, d->daqp.blower+p_qp->nx);
  casadi_copy(d_qp->ubx, p_qp->nx, d->daqp.bupper);
  casadi_copy(d_qp->uba, p_qp->na, d->daqp.bupper+p_qp->nx);
  d->daqp.f = (casadi_real*) (d_qp->g);
  if (d->work.sense) {
    flag = vfdsl_daqp_update(d, warm);
  } else {
    flag = setup_daqp(&d->daqp, &d->work, 0);
    if (flag<0) casadi_daqp_free_mem(d);  /* setup_daqp may leave part of it allocated */
  }
  if (flag>=0) {
    daqp_solve(&d->res, &d->work);
    flag = d->res.exitflag;
  }
  d->work.settings = 0;
  d->return_status = flag;
  d->nodecount = 0;
  d->bnb_itercount = 0;
  d_qp->success = flag==EXIT_OPTIMAL;
  if (d_qp->success) {
    casadi_copy(d->res.lam, p_qp->nx, d_qp->lam_x);
    casadi_copy(d->res.lam+p_qp->nx, p_qp->na, d_qp->lam_a);
    if (d_qp->f) *d_qp->f = d->res.fval;
  } else {
    vfdsl_fill_nan(d_qp->x, p_qp->nx);
    vfdsl_fill_nan(d_qp->lam_x, p_qp->nx);
    vfdsl_fill_nan(d_qp->lam_a, p_qp->na);
    if (d_qp->f) *d_qp->f = NAN;
  }
  return 0;
}

int casadi_daqp_solve(struct casadi_daqp_data* d, const double** arg, double** res, casadi_int* iw, double* w) {
  return vfdsl_daqp_solve(d, 0);
}

