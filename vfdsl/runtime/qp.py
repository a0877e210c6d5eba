"""The tick solver: one CasADi graph from QP data to a safe joint increment.

The compiler hands over ``qp_data(q, u, p, dt) -> (H, g, A, lba, uba, lbx, ubx)`` describing

    minimize 1/2 x'Hx + g'x   subject to   lba <= A x <= uba,   lbx <= x <= ubx        (P)

with H positive definite, x = [dq; slack] (n entries) and m general rows.
:func:`build_step_function` wraps it into ``step(q, u, p, dt, recover) -> (x, status, violation)`` solved
by DAQP through CasADi's ``conic`` plugin, so the whole tick (QP data, solve, fallback) is one
Function that CasADi evaluates or code-generates into one C function.

**Bounds.** lbx > ubx happens only when q is outside its joint limits: the position bound
[q_lo - q, q_hi - q] and the speed bound [-v dt, v dt] (which contains 0) are then disjoint. Such
an entry is pinned to whichever of lbx_j, ubx_j is smaller in magnitude -- the point of the
interval containing 0 (the speed bound) nearest the other one, i.e. a return toward the limits at
full allowed speed. Status bit ``BOUNDS_CLIPPED`` reports it. The clipped box B is never empty.

**Priority levels.** The objective may come in levels (``qp_data`` then also gives Hj, gj, Ej per level): each
level minimizes its own cost over the same rows and box while the rows E_i x of every level above stay within
``BAND_FACTOR * feas_tol`` of their values at that level's answer (:func:`_level_chain`). Each level's cost is
scaled, gets the levels above's curvature (free on the band) and epsilon I, and every level but the last is solved
once more with a proximal term instead of epsilon I, so that no regularization cuts a tracked motion; a level
DAQP cannot solve within its bands is solved again with wider ones before it is given up. H, g (the sum of all
levels) serve phase 2.

**Phase 1** solves (P) over B. DAQP is a dual active-set method: its iterates are dual feasible
and it stops when the primal iterate is feasible, so "x is finite and within ``feas_tol`` of every
row and bound" is equivalent to success; it is checked in the graph (the conic exposes no flag).

**Phase 2** (evaluated only when phase 1 fails, or when the input ``recover`` is nonzero, through a
``Function.if_else`` switch) is
lexicographic. Rows are partitioned into G groups (one per row by default, or one per source
constraint, see ``row_groups``); E in {0,1}^{m x G} is the incidence matrix and t in R^G the
per-group violation.

    (A) least violation:   minimize   1/2 |t|^2 + rho 1't + mu/2 |x|^2
                           subject to  lba - E t <= A x <= uba + E t,   x in B,   t >= 0

    (B) objective:         minimize   1/2 x'Hx + g'x
                           subject to  lba' <= A x <= uba',   x in B
                           (lba'_i = a_i'x_A - tol/100 where a_i'x_A < lba_i, else lba_i; likewise uba')

(A) is always feasible (any x in B with t large enough). Its measure sum_g (rho t_g + t_g^2/2) is
strictly increasing and strictly convex in t, so the least violation t* is unique. With one group
per row it sums over rows; with coarser groups each group counts its worst row (an L-infinity
measure inside one polytope). The linear term makes the penalty exact at t = 0: a group that can
be satisfied is satisfied exactly, since the tie-breaker mu (smallest motion among least-violating
points) has a marginal cost far below rho. The tie-breaker is mu I, not a multiple of H: H's
eigenvalues span ~1e-6..10 on the example tasks, and mu H / trace(H) next to the identity on t made
(A) so ill-conditioned that CasADi's DAQP returned rows violated by up to 2e-7 while reporting
success; with mu I (A) is solved to ~1e-13 (measured).

(B) keeps every row that x_A satisfies hard and relaxes the others just enough to contain x_A (plus
tol/100, so that its feasible set is not a single degenerate point): it is feasible by
construction, and the user's objective acts only inside the least-violation set, so
no row that could hold is traded for tracking. (A) has n + G variables and 2m rows; DAQP is dense,
so G = m costs O((n + m)^3) per solve: pass coarse groups for large m (docs/runtime.md: timings).

(A) is feasible by construction, so its answer is taken unless the solve failed outright (rows or
bounds off by more than 1e-6: a failed solve is off by orders of magnitude), clipped into B (the
solver's bound noise). If (B) fails, x is x_A, a least-violation move without the objective; if (A)
fails, x is the zero motion clipped to B, with status bit ``FALLBACK``. x always lies in B,
and is finite when the QP data are.

``violation[i] = max(lba_i - a_i'x, a_i'x - uba_i, 0)`` for the returned x, set to 0 when below
``feas_tol``, so the caller can name the violated rows by label.
"""

from __future__ import annotations

import enum
import warnings
from collections.abc import Callable, Hashable, Sequence

import casadi as ca
import numpy as np

QP_DATA_OUTPUTS = ("H", "g", "A", "lba", "uba", "lbx", "ubx")
STEP_OUTPUTS = ("x", "status", "violation")
GRADIENT_SATURATION = 1e3
"""K of :func:`_saturated_gradient`: a user push beyond K box widths is saturated."""
BAND_FACTOR = 1.0
"""A lower priority level keeps each higher level's rows E_i x within BAND_FACTOR * feas_tol of their optimal
values: 1e-9 m or rad per tick at vfdsl.compile's feas_tol (0.1 um/s at 10 ms). Thinner bands (1e-11) made DAQP
declare feasible lower levels infeasible: the two sides of a band are nearly parallel rows 2e-11 apart."""
LEVEL_REGULARIZATION = 1e-6
"""epsilon: each priority level's QP is solved with its Hessian scaled to a unit largest diagonal plus epsilon I,
then once more with epsilon (x - x_a)'(x - x_a) / 2 instead (one proximal-point step from the first answer x_a):
the bias epsilon puts on the level's own optimum is multiplied by epsilon / (lambda + epsilon) twice, lambda the
level's curvature along the motion (see :func:`_level_chain`). Below 1e-6 DAQP's answers miss rows by more than
feas_tol (CasADi's DAQP: 9e-8 at 1e-8 on tilt_limited_orbit)."""
LEVEL_ACCEPTANCE = 100.0
"""The answers of the levels above the last, phase 1's included, are accepted within LEVEL_ACCEPTANCE * feas_tol of
the rows (1e-7 m or rad): at epsilon = 1e-6 DAQP meets rows only to ~1e-10..1e-9 (its x is recovered through the
factor of a Hessian of condition 1e6), and a borderline check made the two paths decide differently. The last
level, whose Hessian is the damping's, answers to ~1e-12 and is held to feas_tol; an upper level's answer only
gives the band centres (its E_i x), which are well determined.""" 
WIDE_BAND = 10.0
"""When no solve of a level is acceptable within the band, the level is solved again with the bands of the levels
above WIDE_BAND times wider (1e-8 m or rad per tick, 1 um/s at 10 ms) before it is given up."""
UPPER_CURVATURE = 1.0
"""A lower level's Hessian also gets the (scaled) Hessians of the levels above it: their costs depend on x only
through E_i x, which the band holds, so no minimizer changes; the directions the levels above fix are no longer
flat in the lower level's QP (without it DAQP declared 5 % of lecture_remote_center's level 2 infeasible)."""
PER_ROW_GROUPS_LIMIT = 100
"""Above this many rows one group per row makes phase 2 slow (~30 ms at m = 200; seconds, DAQP
iteration-limit failures and megabytes of generated C at m = 1000): a warning asks for groups."""


class StepStatus(enum.IntFlag):
    """What happened in one tick (the ``status`` output, as bit flags)."""

    OPTIMAL = 0
    LEAST_VIOLATION = 1  # phase 1 gave no feasible point: x solves the least-violation problem
    BOUNDS_CLIPPED = 2   # lbx > ubx somewhere (q outside its joint limits): bounds were clipped
    FALLBACK = 4         # the least-violation QP failed numerically: x is the zero motion clipped to B


def build_step_function(qp_data: ca.Function, prefix: str, *,
                        row_groups: Sequence[Hashable] | None = None,
                        feas_tol: float = 1e-6,
                        penalty: float = 1.0,
                        tie_break: float = 1e-3) -> ca.Function:
    """``prefix(q, u, p, dt, recover) -> (x[n], status, violation[m])`` solving ``qp_data``'s QP.

    ``recover`` nonzero evaluates phase 2 even when phase 1 succeeds: the generated controller does
    it once when it is loaded, so that every solver's workspace exists before the first tick.

    ``row_groups[i]`` is the group of general row i (default: one group per row); ``feas_tol`` the
    absolute tolerance (row units) under which a row or bound counts as satisfied; ``penalty`` is
    rho and ``tie_break`` is mu of phase 2 (see the module docstring).
    """
    levels = _check_qp_data(qp_data)
    n, m = qp_data.size1_out(0), qp_data.size1_out(2)
    inputs = [ca.MX.sym(name, qp_data.sparsity_in(i)) for i, name in enumerate(qp_data.name_in())]
    recover = ca.MX.sym("recover")
    data = [ca.densify(v) for v in qp_data.call(inputs)]
    H, g, A, lba, uba, lbx, ubx = data[:7]
    lo, hi, clipped = _safe_box(lbx, ubx)
    g = _saturated_gradient(H, g, lo, hi)
    if levels > 1:      # (Hj, gj, Ej) per level
        scaled = [_normalized(Hj, gj) for Hj, gj in zip(data[7::3], data[8::3])]
        Hs = [Hj + UPPER_CURVATURE * sum((Hi for Hi, _ in scaled[:j]), ca.MX.zeros(n, n))
              for j, (Hj, _) in enumerate(scaled)]
        Hs = [Hj + LEVEL_REGULARIZATION * ca.MX.eye(n) for Hj in Hs]
        gs = [_saturated_gradient(Hj, gj, lo, hi) for Hj, (_, gj) in zip(Hs, scaled)]
        Es = data[9::3][:-1]
    else:
        Hs, gs, Es = [H], [g], []

    x1 = _daqp(n, m, feas_tol, "phase1_warm")(Hs[0], gs[0], A, lba, uba, lo, hi)
    lower = [*Hs, *gs, *Es]
    chain = _level_chain(n, m, len(Hs), [E.size1() for E in Es], feas_tol)
    if m == 0:
        x, status = chain(x1, A, lba, uba, lo, hi, *lower), ca.MX(int(StepStatus.OPTIMAL))
    else:
        ok1 = _acceptable(x1, A @ x1, lba, uba, lo, hi, feas_tol * (LEVEL_ACCEPTANCE if levels > 1 else 1))
        switch = _phase2_switch([H, g, A, lba, uba, lo, hi, x1, *lower], chain, _incidence(m, row_groups),
                                feas_tol, penalty, tie_break)
        picked = switch(ca.logic_and(ok1, recover == 0), H, g, A, lba, uba, lo, hi, x1, *lower)
        x, status = picked[:n], picked[n]
    # The last line of defence, for every path: x is finite and in B (up to the solver's bound noise,
    # then clipped), or it is the rest motion with FALLBACK.
    safe = _in_box(x, lo, hi, _GROSS_FAILURE)
    x = ca.if_else(safe, _clip(x, lo, hi), _rest(lo, hi))
    status = ca.if_else(safe, status, int(StepStatus.LEAST_VIOLATION) * (m > 0) + int(StepStatus.FALLBACK))
    status = status + int(StepStatus.BOUNDS_CLIPPED) * clipped
    violation = _row_violation(A @ x, lba, uba)
    violation = ca.if_else(violation > feas_tol, violation, 0)
    return ca.Function(prefix, [*inputs, recover], [x, status, violation],
                       [*qp_data.name_in(), "recover"], list(STEP_OUTPUTS))


def _check_qp_data(qp_data: ca.Function) -> int:
    """The number of priority levels: 1 for the 7 outputs of QP_DATA_OUTPUTS, k >= 2 for 7 + 3k outputs
    (Hj, gj, Ej per level)."""
    n_out = qp_data.n_out()
    levels = 1 if n_out == 7 else (n_out - 7) // 3
    if qp_data.n_in() != 4 or n_out < 7 or (n_out != 7 and (levels < 2 or 7 + 3 * levels != n_out)):
        raise ValueError(f"qp_data must map (q, u, p, dt) to {QP_DATA_OUTPUTS} (+ Hj, gj, Ej per priority level), "
                         f"got {qp_data.n_in()} inputs and {n_out} outputs")
    n, m = qp_data.size1_out(0), qp_data.size1_out(2)
    expected = [(n, n), (n, 1), (m, n), (m, 1), (m, 1), (n, 1), (n, 1)]
    if levels > 1:
        for j in range(levels):
            expected += [(n, n), (n, 1), (qp_data.size1_out(9 + 3 * j), n)]
    got = [(qp_data.size1_out(i), qp_data.size2_out(i)) for i in range(n_out)]
    if got != expected:
        raise ValueError(f"qp_data output shapes {got} do not match {expected} for n={n}, m={m}")
    return levels


def _normalized(H: ca.MX, g: ca.MX) -> tuple[ca.MX, ca.MX]:
    """One level's cost scaled to a unit largest Hessian diagonal: no minimizer changes, and DAQP's data stay
    O(1) whatever the weights (with centering at weight 1e6 DAQP answered a level's rows only to ~1e-6, which let
    a redundancy level move a tracked tip 0.2 mm in 2 s)."""
    scale = ca.mmax(ca.diag(H))
    return H / scale, g / scale


def _level_chain(n: int, m: int, levels: int, e_rows: list[int], tol: float) -> ca.Function:
    """chain(x1, A, lba, uba, lo, hi, H1..Hk, g1..gk, E1..E(k-1)) -> x: the priority levels, from level 1's first
    answer x1 (phase 1, known acceptable) on.

    Each level j minimizes its own cost (Hj, gj: scaled, with the levels above's curvature and epsilon I, see
    UPPER_CURVATURE and LEVEL_REGULARIZATION) over the rows and the box, and keeps every level above it optimal:
    the rows E_i x of the levels i < j stay within BAND of their values at x_i, level i's own answer (E_i is the
    stack of level i's terms, so its optimal set is {x : E_i x = E_i x_i}; centred on x_i, not on the level just
    above, the levels below cannot walk a band width further each). Every level but the last
    is then solved once more with the proximal term epsilon |x - x_a|^2 / 2 instead of epsilon |x|^2 / 2, x_a its
    first answer: the first solve's bias on the level's optimum, epsilon / (lambda + epsilon) of the motion along
    a direction where the level's curvature is lambda (a tool tip turned about a port 4 mm away: lambda ~ 2e-5),
    is multiplied by that factor again. The last level (the redundancy terms, usually damping) keeps its
    epsilon: it only chooses among motions the levels above leave free.

    A level none of whose solves is acceptable (rows, bounds, or its bands by more than another band width) is
    solved again with WIDE_BAND times wider bands, and if that fails too it keeps the answer before it: a lower
    level can never undo a higher one."""
    x1 = ca.MX.sym("x1", n)
    A = ca.MX.sym("A", m, n)
    lba, uba, lo, hi = (ca.MX.sym(name, size) for name, size in (("lba", m), ("uba", m), ("lo", n), ("hi", n)))
    Hs = [ca.MX.sym(f"H{j}", n, n) for j in range(1, levels + 1)]
    gs = [ca.MX.sym(f"g{j}", n) for j in range(1, levels + 1)]
    Es = [ca.MX.sym(f"E{j}", rows, n) for j, rows in enumerate(e_rows, start=1)]
    band = BAND_FACTOR * tol
    eps = LEVEL_REGULARIZATION

    def level(j, width, tag) -> ca.Function:
        """level(x_prev, at, kept, A, lba, uba, lo, hi, Hj, gj) -> (x, ok): level j within bands of ``width``
        around ``at`` on the rows ``kept`` (x_prev when no solve is acceptable; ok: a solve was). A Function of its
        own, so that a switch can call it without recomputing the levels above."""
        rows = sum(e_rows[:j - 1])
        x_prev, at, kept = ca.MX.sym("x_prev", n), ca.MX.sym("at", rows), ca.MX.sym("kept", rows, n)
        A_, lba_, uba_ = ca.MX.sym("A", m, n), ca.MX.sym("lba", m), ca.MX.sym("uba", m)
        lo_, hi_, Hj, gj = ca.MX.sym("lo", n), ca.MX.sym("hi", n), ca.MX.sym("H", n, n), ca.MX.sym("g", n)
        A_j, lb_j, ub_j = ca.vertcat(A_, kept), ca.vertcat(lba_, at - width), ca.vertcat(uba_, at + width)

        def acceptable(x_new):
            rows_tol = tol if j == levels else tol * LEVEL_ACCEPTANCE
            return ca.logic_and(_acceptable(x_new, A_j @ x_new, lb_j, ub_j, lo_, hi_, rows_tol),
                                ca.mmax(_row_violation(kept @ x_new, at - width, at + width)) <= width)

        x_a = _daqp(n, m + rows, tol, f"level{j}{tag}_warm")(Hj, gj, A_j, lb_j, ub_j, lo_, hi_)
        ok = acceptable(x_a)
        x = ca.if_else(ok, x_a, x_prev)
        if j < levels:      # the proximal step from the level's first answer
            x_b = _daqp(n, m + rows, tol, f"level{j}{tag}_prox_warm")(Hj, gj - eps * x, A_j, lb_j, ub_j, lo_, hi_)
            ok_b = acceptable(x_b)
            x = ca.if_else(ok_b, x_b, x)
            ok = ca.logic_or(ok, ok_b)
        return ca.Function(f"level{j}{tag}", [x_prev, at, kept, A_, lba_, uba_, lo_, hi_, Hj, gj], [x, ok])

    x = x1
    if levels > 1:          # level 1's proximal step (its first answer is phase 1's)
        x_b = _daqp(n, m, tol, "level1_prox_warm")(Hs[0], gs[0] - eps * x1, A, lba, uba, lo, hi)
        ok_b = (_acceptable(x_b, A @ x_b, lba, uba, lo, hi, tol * LEVEL_ACCEPTANCE) if m
                else _in_box(x_b, lo, hi, tol * LEVEL_ACCEPTANCE))
        x = ca.if_else(ok_b, x_b, x1)
    centers = [Es[0] @ x] if levels > 1 else []
    for j in range(2, levels + 1):
        args = [x, ca.vertcat(*centers), ca.vertcat(*Es[:j - 1]), A, lba, uba, lo, hi, Hs[j - 1], gs[j - 1]]
        x_narrow, ok = level(j, band, "")(*args)
        # DAQP (CasADi's) can call a feasible level infeasible, or miss its rows, where the band pins a
        # degenerate vertex (every joint at its speed bound): solved again with bands WIDE_BAND times wider, only
        # on such ticks (a switch between Functions: neither branch recomputes the levels above)
        wide = level(j, WIDE_BAND * band, "_wide")
        symbols = [ca.MX.sym(f"a{k}", v.sparsity()) for k, v in enumerate([x_narrow, *args])]
        keep = ca.Function(f"level{j}_keep", symbols, [symbols[0]])
        retry = ca.Function(f"level{j}_retry", symbols, [wide(*symbols[1:])[0]])
        x = ca.Function.if_else(f"level{j}_if_failed", keep, retry)(ok, x_narrow, *args)
        if j < levels:
            centers.append(Es[j - 1] @ x)       # level j's optimal values, held by every level below
    return ca.Function("priority_levels", [x1, A, lba, uba, lo, hi, *Hs, *gs, *Es], [x])


def _daqp(n: int, m: int, feas_tol: float, name: str) -> Callable[..., ca.MX]:
    """solve(H, g, A, lba, uba, lbx, ubx) -> x: dense DAQP conic, no exception on failure.

    The variable bounds reach DAQP as identity rows: through CasADi's interface (3.8) DAQP met simple
    bounds only to ~5e-8 (measured), general rows to ``primal_tol``."""
    sparsity = {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity.dense(m + n, n)}
    options = {"error_on_fail": False, "daqp": {"primal_tol": feas_tol * 1e-3}}
    conic = ca.conic(name, "daqp", sparsity, options)
    free = ca.inf * ca.DM.ones(n)

    def solve(H, g, A, lba, uba, lbx, ubx):
        return conic(h=H, g=g, a=ca.vertcat(A, ca.DM.eye(n)), lba=ca.vertcat(lba, lbx),
                     uba=ca.vertcat(uba, ubx), lbx=-free, ubx=free)["x"]

    return solve


def _saturated_gradient(H: ca.MX, g: ca.MX, lo: ca.MX, hi: ca.MX) -> ca.MX:
    """g, scaled down (never up) so that |g|_inf <= K ||H||_inf W, W the largest finite bound of B.

    ||H||_inf >= lambda_max(H), so an unscaled |g|_inf above that limit puts the unconstrained step
    -H^-1 g at least K W from the origin: the answer is saturated by the bounds either way, and the
    scaled g keeps its direction while DAQP's transformed data (R^-T g, A H^-1 g) stay far from
    overflow and from swamping the rows' offsets. Never active on the example tasks' normal ticks."""
    finite_abs = lambda b: ca.if_else(ca.fabs(b) < ca.inf, ca.fabs(b), 0)  # noqa: E731
    width = ca.mmax(ca.fmax(finite_abs(lo), finite_abs(hi)))
    limit = GRADIENT_SATURATION * ca.mmax(ca.sum2(ca.fabs(H))) * width
    g_max = ca.mmax(ca.fabs(g))
    return g * ca.if_else(ca.logic_and(width > 0, g_max > limit), limit / g_max, 1)


def _safe_box(lbx: ca.MX, ubx: ca.MX) -> tuple[ca.MX, ca.MX, ca.MX]:
    """B = [lo, hi]: crossed entries pinned to the bound of smaller magnitude; flag if any."""
    crossed = lbx > ubx
    pin = ca.if_else(ca.fabs(lbx) <= ca.fabs(ubx), lbx, ubx)
    return ca.if_else(crossed, pin, lbx), ca.if_else(crossed, pin, ubx), ca.mmax(crossed)


def _row_violation(Ax: ca.MX, lower: ca.MX, upper: ca.MX) -> ca.MX:
    """max(lower - Ax, Ax - upper, 0), elementwise."""
    return ca.fmax(ca.fmax(lower - Ax, Ax - upper), 0)


def _in_box(x, lo, hi, tol) -> ca.MX:
    """1 when x is finite and within tol of the box [lo, hi]."""
    finite = ca.mmin(ca.fabs(x) < ca.inf)
    return ca.logic_and(finite, ca.mmax(_row_violation(x, lo, hi)) <= tol)


def _acceptable(x, Ax, lba, uba, lo, hi, tol) -> ca.MX:
    """1 when x is finite and within tol of every row and bound."""
    return ca.logic_and(_in_box(x, lo, hi, tol), ca.mmax(_row_violation(Ax, lba, uba)) <= tol)


def _clip(x, lo, hi) -> ca.MX:
    """x clipped into [lo, hi]; only ever applied to a finite x (fmax(NaN, lo) is lo, not NaN)."""
    return ca.fmin(ca.fmax(x, lo), hi)


def _rest(lo, hi) -> ca.MX:
    """The safe motion: zero, or the point of B nearest zero when q is outside its joint limits."""
    return _clip(ca.MX.zeros(lo.sparsity()), lo, hi)


def _incidence(m: int, row_groups: Sequence[Hashable] | None) -> ca.DM:
    """E[i, k] = 1 when row i belongs to the k-th distinct group (first-seen order)."""
    if row_groups is None:
        if m > PER_ROW_GROUPS_LIMIT:
            warnings.warn(f"{m} general rows and no row_groups: phase 2 gets {m} slack variables; "
                          "pass one group per source constraint", stacklevel=3)
        return ca.DM(ca.Sparsity.diag(m), 1.0)
    if len(row_groups) != m:
        raise ValueError(f"row_groups has {len(row_groups)} entries for {m} general rows")
    ids = {group: k for k, group in enumerate(dict.fromkeys(row_groups))}
    E = np.zeros((m, len(ids)))
    E[np.arange(m), [ids[group] for group in row_groups]] = 1.0
    return ca.sparsify(ca.DM(E))


def _phase2_switch(values: list[ca.MX], chain: ca.Function, E: ca.DM, tol, rho, mu) -> ca.Function:
    """switch(ok, H, g, A, lba, uba, lo, hi, x1, *lower) -> [chain(x1, ...); 0] when ok (the priority levels
    below the first, ``lower`` their data), else phase 2's [x; status].

    The branches are Functions of values already computed: a short-circuit ``if_else`` on
    expressions would make each branch recompute them (QP data and phase 1) from the inputs.
    """
    names = ("H", "g", "A", "lba", "uba", "lo", "hi", "x1")
    args = [ca.MX.sym(names[k] if k < len(names) else f"level_{k}", v.sparsity()) for k, v in enumerate(values)]
    H, g, A, lba, uba, lo, hi, x1 = args[:8]
    keep = ca.Function("keep", args, [ca.vertcat(chain(x1, A, lba, uba, lo, hi, *args[8:]),
                                                 int(StepStatus.OPTIMAL))])
    recover = ca.Function("recover", args,
                          [_least_violation(H, g, A, lba, uba, lo, hi, E, tol, rho, mu)])
    return ca.Function.if_else("phase2_if_needed", keep, recover)


# (B)'s rows are relaxed already; its check only has to catch a failed solve, whose answer is off by
# orders of magnitude (seen: 1 to 20), not decide feasibility at the 1e-9 level, where the generated and
# interpreted evaluations (whose QP data differ in the last bits) could decide differently.
_GROSS_FAILURE = 1e-6


def _least_violation(H, g, A, lba, uba, lo, hi, E: ca.DM, tol, rho, mu) -> ca.MX:
    """Phase 2 (A then B), returning [x; status]."""
    n, m, G = H.size1(), A.size1(), E.size2()
    H_a = ca.diagcat(mu * ca.DM.eye(n), ca.DM.eye(G))
    g_a = ca.vertcat(ca.DM.zeros(n), rho * ca.DM.ones(G))
    A_a = ca.vertcat(ca.horzcat(A, E), ca.horzcat(A, -E))
    inf_m, inf_G = ca.inf * ca.DM.ones(m), ca.inf * ca.DM.ones(G)
    lba_a, uba_a = ca.vertcat(lba, -inf_m), ca.vertcat(inf_m, uba)
    lbz, ubz = ca.vertcat(lo, ca.DM.zeros(G)), ca.vertcat(hi, inf_G)
    z = _daqp(n + G, 2 * m, tol, "phase2a")(H_a, g_a, A_a, lba_a, uba_a, lbz, ubz)
    x_a = _clip(z[:n], lo, hi)      # used only when (A) is acceptable, i.e. z is finite
    Ax_a = A @ x_a
    margin = 1e-2 * tol                                  # > DAQP's primal tolerance (1e-3 tol)
    lba_b = ca.if_else(Ax_a < lba, Ax_a - margin, lba)   # only the rows x_a violates are relaxed
    uba_b = ca.if_else(Ax_a > uba, Ax_a + margin, uba)
    x_b = _daqp(n, m, tol, "phase2b")(H, g, A, lba_b, uba_b, lo, hi)

    # Acceptance is decided on the solver's own answers, before any clipping: clipping a failed
    # solve's NaN into B would turn it into a full-speed motion that looks feasible.
    ok_a = _acceptable(z, A_a @ z, lba_a, uba_a, lbz, ubz, _GROSS_FAILURE)
    ok_b = _acceptable(x_b, A @ x_b, lba_b, uba_b, lo, hi, _GROSS_FAILURE)
    x = ca.if_else(ok_a, ca.if_else(ok_b, _clip(x_b, lo, hi), x_a), _rest(lo, hi))
    status = int(StepStatus.LEAST_VIOLATION) + int(StepStatus.FALLBACK) * (1 - ok_a)
    return ca.vertcat(x, status)
