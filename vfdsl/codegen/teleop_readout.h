/* vfdsl: a teleoperated task's readout after each tick in plain C (the library `vfdsl export` writes): the haptic
 * force, the set-point, the goal, the master's depth, following or not and the rows that acted, from the generated
 * <prefix>_teleop_readout (vfdsl/objectives/haptics.py: the math; Python evaluates the same function from the task's
 * library), with its state kept between ticks.
 *
 * Include it after checked_step.h when the generated header defines VFDSL_TELEOP. vfdsl_teleop_open allocates
 * everything (work arrays, a memory slot); vfdsl_teleop_eval neither allocates, locks nor makes a system call.
 */
#ifndef VFDSL_TELEOP_READOUT_H
#define VFDSL_TELEOP_READOUT_H

#define VFDSL_READOUT VFDSL_CAT(VFDSL_PREFIX, _teleop_readout)
#define VFDSL_READOUT_WORK VFDSL_CAT(VFDSL_PREFIX, _teleop_readout_work)
#define VFDSL_READOUT_CHECKOUT VFDSL_CAT(VFDSL_PREFIX, _teleop_readout_checkout)
#define VFDSL_READOUT_RELEASE VFDSL_CAT(VFDSL_PREFIX, _teleop_readout_release)

typedef struct {
  double state[VFDSL_TELEOP_STATE + 1];    /* per teleop term: previous depth (3), force (3), warm, engaged time */
  double next[VFDSL_TELEOP_STATE + 1];
  double force[3], setpoint[6], goal[3], depth[3], following[1];
  double acting[VFDSL_TELEOP_ROWS + 1];    /* per constraint row: 1 when it acted */
  const casadi_real** arg;
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
  int slot;
} vfdsl_teleop;

/* Allocate the work arrays and check out a memory slot (VFDSL_OPENED, VFDSL_NO_MEMORY or VFDSL_NO_SLOT); the state
 * of the first tick. Call vfdsl_teleop_close in every case. */
static int vfdsl_teleop_open(vfdsl_teleop* t) {
  casadi_int n[4];
  VFDSL_READOUT_WORK(&n[0], &n[1], &n[2], &n[3]);
  memset(t->state, 0, sizeof t->state);
  t->slot = -1;
  if (!vfdsl_work_open(n, n, &t->arg, &t->res, &t->iw, &t->w)) return VFDSL_NO_MEMORY;
  t->slot = VFDSL_READOUT_CHECKOUT();
  return t->slot < 0 ? VFDSL_NO_SLOT : VFDSL_OPENED;
}

static void vfdsl_teleop_close(vfdsl_teleop* t) {
  if (t->slot >= 0) VFDSL_READOUT_RELEASE(t->slot);
  t->slot = -1;
  free(t->arg); free(t->res); free(t->iw); free(t->w);
  t->arg = 0; t->res = 0; t->iw = 0; t->w = 0;
}

/* The readout of the tick core c has just evaluated (its q, u, p, dt and x; a procedure's activity): 0, or the
 * generated function's nonzero return code. The state advances only when it succeeds. */
static int vfdsl_teleop_eval(vfdsl_teleop* t, const vfdsl_core* c, const double* activity) {
  int k = 0, code;
  t->arg[k++] = c->data[VFDSL_Q];
  t->arg[k++] = c->data[VFDSL_U];
  t->arg[k++] = c->data[VFDSL_P];
  t->arg[k++] = c->data[VFDSL_DT];
  if (activity) t->arg[k++] = activity;
  t->arg[k++] = c->data[VFDSL_X];
  t->arg[k++] = t->state;
  t->res[0] = t->force;
  t->res[1] = t->setpoint;
  t->res[2] = t->goal;
  t->res[3] = t->depth;
  t->res[4] = t->following;
  t->res[5] = t->acting;
  t->res[6] = t->next;
  code = VFDSL_READOUT(t->arg, t->res, t->iw, t->w, t->slot);
  if (!code) memcpy(t->state, t->next, sizeof(double) * VFDSL_TELEOP_STATE);
  return code;
}

/* Back to the first tick's state (no previous depth or force). */
static void vfdsl_teleop_reset(vfdsl_teleop* t) {
  memset(t->state, 0, sizeof t->state);
}

#endif
