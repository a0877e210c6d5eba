"""An independent solution of a tick's priority levels, for tests: each level in turn with DAQP's Python
package (a newer DAQP than the one CasADi bundles, called directly, no scaling, no regularization of ours),
over x = x0 + N z where N spans the null space of the levels above (numpy's SVD): their terms' rows E_i x are
held *exactly* at their optimal values, not within a band.

    levels = level_data(ctrl, q, inputs)           # [(Hj, gj, Ej)], rows and bounds, from qp_data's (Rj, rj)
    x, ok = lexicographic(*levels)
    worse(levels[0], x_step, x)                    # > 0: the step is not optimal at some level
"""

from __future__ import annotations

import dataclasses

import daqp
import numpy as np

from vfdsl.compiler.assemble import HESSIAN_FLOOR

BIG = 1e30


def level_data(ctrl, q, inputs, params=None, dt=None):
    """([(Hj, gj, Ej) per level], A, lba, uba, lbx, ubx) of one tick, from the controller's qp_data: level j's
    cost 1/2 |Rj x - rj|^2 as Hj = Rj'Rj + floor I, gj = -Rj'rj, and its rows Ej = Rj."""
    v = ctrl._values
    p = v.params(params)
    args = (v.q(q), v.inputs(inputs), ctrl.assembled.context.layout.defaults if p is None else p, v.dt(dt))
    out = [np.array(x) for x in ctrl.assembled.function(*args)]
    H, g, A, lba, uba, lbx, ubx = out[:7]
    floor = HESSIAN_FLOOR * np.eye(H.shape[0])
    levels = [(out[i].T @ out[i] + floor, -out[i].T @ out[i + 1].ravel(), out[i]) for i in range(7, len(out), 2)]
    if not levels:
        levels = [(H, g.ravel(), np.zeros((0, H.shape[0])))]
    return levels, A, lba.ravel(), uba.ravel(), lbx.ravel(), ubx.ravel()


def box(lbx, ubx):
    """The step's box B: crossed bounds pinned to the one of smaller magnitude (docs/runtime.md, Bounds)."""
    lo, hi = lbx.copy(), ubx.copy()
    crossed = lo > hi
    pin = np.where(np.abs(lo) <= np.abs(hi), lo, hi)
    lo[crossed], hi[crossed] = pin[crossed], pin[crossed]
    return lo, hi


def _solve(H, g, A, lb, ub):
    n = H.shape[0]
    x, _, flag, _ = daqp.solve(np.ascontiguousarray(H), np.ascontiguousarray(g, dtype=float),
                               np.ascontiguousarray(A.reshape(-1, n)), np.minimum(ub, BIG).astype(float),
                               np.maximum(lb, -BIG).astype(float), np.zeros(len(ub), dtype=np.intc),
                               primal_tol=1e-12, iter_limit=100000)
    return np.array(x), flag >= 1


def lexicographic(levels, A, lba, uba, lbx, ubx, slack=1e-12):
    """The levels' lexicographic optimum, and whether every level's solve succeeded. Below level 1 a row that
    the level above leaves violated by v (its solver's accuracy) may stay violated by v + ``slack``."""
    lo, hi = box(lbx, ubx)
    n = len(lo)
    rows, lb, ub = np.vstack([A.reshape(-1, n), np.eye(n)]), np.r_[lba, lo], np.r_[uba, hi]
    x0, N, kept = np.zeros(n), np.eye(n), np.zeros((0, n))
    for H, g, E in levels:
        r = rows @ x0
        first = not kept.shape[0]
        lz = lb - r if first else np.minimum(lb - r, 0) - slack
        uz = ub - r if first else np.maximum(ub - r, 0) + slack
        z, ok = _solve(N.T @ H @ N, N.T @ (H @ x0 + g), rows @ N, lz, uz)
        if not ok:
            return x0, False
        x0 = x0 + N @ z
        kept = np.vstack([kept, E])
        _, s, vt = np.linalg.svd(kept)
        N = vt[int(np.sum(s > 1e-9 * s[0])):].T
        if N.shape[1] == 0:
            break
    return x0, True


def robust(levels, A, lba, uba, lbx, ubx):
    """:func:`lexicographic`, retried with a larger ``slack`` when a level's solve fails numerically; not ok when
    no answer meets the rows and bounds within 1e-9 (the reference's solver missed them)."""
    lo, hi = box(lbx, ubx)
    for slack in (1e-12, 1e-11, 1e-10):
        x, ok = lexicographic(levels, A, lba, uba, lbx, ubx, slack)
        Ax = A.reshape(-1, len(x)) @ x
        missed = max(np.max(np.r_[lba - Ax, Ax - uba, 0]), np.max(np.r_[lo - x, x - hi, 0]))
        if ok and missed <= 1e-9:
            return x, True
    return x, False


def worse(levels, x, x_ref, close=1e-8):
    """At the first level whose terms' rows E x differ from the reference's by more than ``close`` (m or rad per
    tick: ten band widths; a dropped level is 1e-5..1e-2 away), how much more x costs there than x_ref,
    relative; 0 when every level agrees (<= 0: x is as good as the reference there). Within a band width of a
    level's optimum, a degenerate level below it (every joint at its speed bound) can cost 1e-3 more or less."""
    return first_worse(levels, x, x_ref, close)[1]


def first_worse(levels, x, x_ref, close=1e-8):
    """(j, :func:`worse`): also the index of the level it is measured at (len(levels) when every level agrees)."""
    for j, (H, g, E) in enumerate(levels):
        if np.abs(E @ (x - x_ref)).max(initial=0) <= close:
            continue
        cost, cost_ref = (0.5 * y @ H @ y + g @ y for y in (x, x_ref))
        return j, (cost - cost_ref) / max(abs(cost_ref), 1e-300)
    return len(levels), 0.0


TIE_BREAK = 1e-6        # vfdsl.runtime.qp.LEVEL_TIE_BREAK, restated: the last level, damping, is solved with it


def kkt_excess(qp, x, last_is_damping: bool, active=1e-9):
    """How far x is from each level's optimum, by that level's own KKT conditions over the hard rows and the optimal
    sets of the levels above (the issue's oracle): for level j, its gradient G_j = R_j'(R_j x - r_j) against the rows
    of the levels above (multipliers of any sign: the optimal set of a least-squares level is R_i x = R_i x*) and the
    hard rows and bounds at a bound within ``active`` (each with the sign of the bound holding x, >= 0), by scipy's
    bounded least squares (BVLS), relative to the gradient's scale |R_j| (|R_j| |x| + |r_j|) as the certificate's
    (docs/runtime.md). The last level, damping alone, is solved with its documented tie-break: scaled to a unit
    largest diagonal, plus TIE_BREAK I. Also the hard rows' largest excess (unit rows, m or rad per tick).
    Returns ([relative residual per level], hard rows' excess)."""
    from scipy.optimize import lsq_linear
    n = len(x)
    norms = np.linalg.norm(qp.A, axis=1)
    unit = np.where(norms > 0, norms, 1)
    A, lb, ub = qp.A / unit[:, None], qp.lb / unit, qp.ub / unit
    Ax = A @ x
    excess = float(np.max(np.r_[lb - Ax, Ax - ub, 0.0]))
    held = [(A[i], 1.0) for i in range(len(Ax)) if Ax[i] >= ub[i] - active] + \
           [(A[i], -1.0) for i in range(len(Ax)) if Ax[i] <= lb[i] + active and not Ax[i] >= ub[i] - active]
    S = np.array([s * a for a, s in held]).reshape(-1, n).T               # columns s_i a_i, multipliers >= 0
    residuals = []
    for j, level in enumerate(qp.levels):
        R, r = level.R, level.r
        G = R.T @ (R @ x - r)
        scale = np.linalg.norm(R) * (np.linalg.norm(R) * np.linalg.norm(x) + np.linalg.norm(r))
        if last_is_damping and j == len(qp.levels) - 1:
            s = 1 / max(np.max(np.diag(R.T @ R)), 1e-300)
            G = s * G + TIE_BREAK * x
            scale = s * scale + TIE_BREAK * np.linalg.norm(x)
        above = np.vstack([lv.R for lv in qp.levels[:j]]).T if j else np.zeros((n, 0))
        M = np.hstack([above, S])
        if M.shape[1] == 0:
            residual = np.linalg.norm(G)
        else:
            lower = np.r_[np.full(above.shape[1], -np.inf), np.zeros(S.shape[1])]
            fit = lsq_linear(M, -G, bounds=(lower, np.full(M.shape[1], np.inf)), method="bvls", tol=1e-15)
            residual = np.linalg.norm(M @ fit.x + G)
        residuals.append(float(residual / max(scale, 1e-300)))
    return residuals, excess


PENALTY, LEAST_VIOLATION_TIE_BREAK = 1.0, 1e-3     # vfdsl.compile's penalty rho and tie_break mu, restated
MARGIN = 1e-8               # vfdsl.runtime.qp.LEAST_VIOLATION_MARGIN feas_tol, restated
FLOOR = 1e-4                # vfdsl.runtime.qp.REST_VIOLATION_FLOOR, restated
RELAXED = 1e-12             # a group counts as violated above this (1e-3 feas_tol, as the controller)


def least_violation_set(qp, groups):
    """(x_A, qp over S): phase 2's least violation solved here, and the tick's QP with its general rows' bounds those
    of the least-violation set S over which the levels act (docs/runtime.md, Phase 2), from their definitions: (A)
    stacked here and solved by DAQP's Python package directly (tight tolerance, no scaling); each row of a violated
    group relaxed by the group's least violation and the margin; in (A) no row worse than at rest by more than its
    group's worst comes back (v_g - t_g, v_g the group's largest violation at rest, x_0 the point of the box nearest
    0), in S no row worse than at rest or at x_A; each group's penalty rho t_g / max(v_g, FLOOR)."""
    n = qp.P.shape[0]
    A, lb, ub = qp.A[n:], qp.lb[n:], qp.ub[n:]
    lo, hi = box(qp.lb[:n], qp.ub[:n])
    ids = {g: k for k, g in enumerate(dict.fromkeys(groups))}
    m, G = len(lb), len(ids)
    E = np.zeros((m, G))
    E[np.arange(m), [ids[g] for g in groups]] = 1
    at_rest = A @ np.clip(0.0, lo, hi)
    worst_at_rest = np.zeros(G)
    np.maximum.at(worst_at_rest, [ids[g] for g in groups], np.maximum(np.maximum(lb - at_rest, at_rest - ub), 0))
    H = np.diag(np.r_[np.full(n, LEAST_VIOLATION_TIE_BREAK), np.ones(G)])
    f = np.r_[np.zeros(n), PENALTY / np.maximum(worst_at_rest, FLOOR)]
    held = worst_at_rest[[ids[g] for g in groups]]
    rows = np.vstack([np.hstack([A, E]), np.hstack([A, -E])])
    lower = np.r_[lo, np.zeros(G), lb, np.minimum(lb, at_rest) - held]
    upper = np.r_[hi, np.full(G, BIG), np.maximum(ub, at_rest) + held, ub]
    z, _, flag, _ = daqp.solve(H, f, rows, np.minimum(upper, BIG), np.maximum(lower, -BIG),
                               np.zeros(n + G + 2 * m, dtype=np.intc), primal_tol=1e-13, iter_limit=100000)
    assert flag >= 1, flag
    z = np.array(z)
    relaxed = E @ z[n:]
    widened = np.where(relaxed > RELAXED, relaxed + MARGIN, 0.0)
    at_a = A @ np.clip(z[:n], lo, hi)
    lower = np.maximum(lb - widened, np.minimum(lb, np.minimum(at_rest, at_a)))
    upper = np.minimum(ub + widened, np.maximum(ub, np.maximum(at_rest, at_a)))
    return z[:n], dataclasses.replace(qp, lb=np.r_[qp.lb[:n], lower], ub=np.r_[qp.ub[:n], upper])


FEASIBILITY = 1e-9          # vfdsl.pipeline.FEASIBILITY_TOLERANCE, restated
TRIALS, SLOPE_STEP, DECREASE, AGREEMENT = 6, 1e-4, 0.1, 0.9     # vfdsl.runtime.line_search's, restated


def whole_step(ctrl):
    """The controller's step with phase 2's step taken whole (no step length, ``backtrack=False``), interpreted:
    ``f(q, u, p, dt, recover) -> (x, status, violation)`` of the task's own QP data."""
    from vfdsl.runtime import BufferedFunction, build_step_function
    problem = ctrl.assembled
    return BufferedFunction.interpreted(build_step_function(
        problem.function, "whole_step", row_groups=problem.row_groups, feas_tol=FEASIBILITY,
        last_level_is_cost=problem.last_level_is_damping, backtrack=False))


def step_length(ctrl, q, inputs, params, x):
    """a: how far along phase 2's step x (its whole step) the tick goes (docs/runtime.md, Phase 2 (C)), restated
    from the definition: the measure sum_g rho t_g / w_g + t_g^2 / 2 over the hard rows (no slack column) of the
    groups off at rest, t_g their largest violation at rest in the QP at q + a dq (``ctrl.problem`` there, dead
    zone FEASIBILITY), w_g = max(v_g, FLOOR); the largest a of 1, 1/2, ..., 1/32 with phi(a) < phi(0) + c a min(s,
    0), s the difference quotient over SLOPE_STEP, else 0; 1 where the box forces a motion, where nothing is off,
    and where s > AGREEMENT m, m the same quotient of the measure the tick's linearized rows give."""
    qp = ctrl.problem(q, inputs, params)
    n, nq = qp.P.shape[0], qp.nq
    lo, hi = box(qp.lb[:n], qp.ub[:n])
    if np.any(np.clip(0.0, lo, hi) != 0):
        return 1.0
    A = qp.A[n:]
    ids = {g: k for k, g in enumerate(dict.fromkeys(ctrl.assembled.row_groups))}
    group = np.array([ids[g] for g in ctrl.assembled.row_groups], dtype=int)

    def worst(violation):
        t = np.zeros(len(ids))
        np.maximum.at(t, group, violation)
        return t

    v = worst(np.maximum(np.maximum(qp.lb[n:], -qp.ub[n:]), 0))
    counted = ~np.any(A[:, nq:] != 0, axis=1) & (v[group] > FEASIBILITY)
    w = np.maximum(v, FLOOR)

    def measure(violation):
        t = worst(np.where(counted, violation, 0))
        t = np.where(t > FEASIBILITY, t, 0)
        return float(np.sum(PENALTY * t / w + t * t / 2))

    def phi(a):
        at = ctrl.problem(q + a * x[:nq], inputs, params)
        return measure(np.maximum(np.maximum(at.lb[n:], -at.ub[n:]), 0))

    phi0 = phi(0.0)
    if phi0 == 0:
        return 1.0
    slope = (phi(SLOPE_STEP) - phi0) / SLOPE_STEP
    moved = A @ (SLOPE_STEP * x)
    predicted = (measure(np.maximum(np.maximum(qp.lb[n:] - moved, moved - qp.ub[n:]), 0)) - phi0) / SLOPE_STEP
    if slope > AGREEMENT * predicted:       # the rows mislead along x: the step whole
        return 1.0
    for k in range(TRIALS):
        a = 0.5 ** k
        if phi(a) < phi0 + DECREASE * a * min(slope, 0.0):
            return a
    return 0.0
