"""The tick solver: one CasADi graph from QP data to a safe joint increment.

The compiler hands over ``qp_data(q, u, p, dt) -> (H, g, A, lba, uba, lbx, ubx)`` describing

    minimize 1/2 x'Hx + g'x   subject to   lba <= A x <= uba,   lbx <= x <= ubx        (P)

with H positive definite, x = [dq; slack] (n entries) and m general rows.
:func:`build_step_function` wraps it into ``step(q, u, p, dt, recover) -> (x, status, violation)`` solved
by DAQP through CasADi's ``conic`` plugin (each solve: :mod:`vfdsl.runtime.daqp_solve`), so the whole tick (QP data,
solve, fallback) is one Function that CasADi evaluates or code-generates into one C function.

**Bounds.** lbx > ubx happens only when q is outside its joint limits: the position bound
[q_lo - q, q_hi - q] and the speed bound [-v dt, v dt] (which contains 0) are then disjoint. Such
an entry is pinned to whichever of lbx_j, ubx_j is smaller in magnitude -- the point of the
interval containing 0 (the speed bound) nearest the other one, i.e. a return toward the limits at
full allowed speed. Status bit ``BOUNDS_CLIPPED`` reports it. The clipped box B is never empty.

**Priority levels.** The objective may come in levels (``qp_data`` then also gives Rj, rj per level, level j's
cost being 1/2 |Rj x - rj|^2): phase 1 is then the levels solved exactly over a working set and certified
(:mod:`vfdsl.runtime.lexls`: the generated C tries the previous tick's working set first), else one call of DAQP's
hierarchical mode (Arnström & Axehill's lexicographic least squares, in the daqp sources the generated C is built
from), whose answer is solved again exactly over the rows it holds, or taken from there to the optimum by the primal
active-set method of :func:`vfdsl.runtime.lexls.from_feasible`, and taken when certified. The rows and the box are
level 0, hard; level 1 minimizes its squared errors over them, level 2 over the optimal set of level 1, and so on; DAQP's
own cost acts last: the task's last level when it is damping alone (``last_level_is_cost``; plus
``LEVEL_TIE_BREAK`` I), else |x|^2 / 2, the smallest motion among what the levels leave free. Each level's rows are scaled to a
longest row of 1 (no minimizer changes) and weighted in the problem's scale (``LEVEL_ATTEMPTS``), so that a
level weighs its terms as the task says; a tick where DAQP fails a level is solved again with another weight.

**Phase 1** solves (P) over B. DAQP is a dual active-set method: its iterates are dual feasible
and it stops when the primal iterate is feasible, so "x is finite and within ``feas_tol`` of every
row and bound" is equivalent to success; it is checked in the graph (the conic exposes no flag).

**Phase 2** (evaluated only when phase 1 fails, or when the input ``recover`` is nonzero, through a
``Function.if_else`` switch) is
lexicographic. Rows are partitioned into G groups (one per row by default, or one per source
constraint, see ``row_groups``); E in {0,1}^{m x G} is the incidence matrix and t in R^G the
per-group violation.

    (A) least violation:   minimize   1/2 |t|^2 + rho sum_g t_g / w_g + mu/2 |x|^2,   w_g = max(v_g, 1e-4)
                           subject to  lba - E t <= A x <= uba + E t,   x in B,   t >= 0,
                                       min(lba, A x_0) - E (v - t) <= A x <= max(uba, A x_0) + E (v - t)
                                       (x_0: the rest motion in B)

    (B) the levels:        phase 1's levels (or its one cost), lexicographically, over the least-violation set
                           S = {x in B : max(lba - E t', min(lba, A x_0, A x_A)) <= A x
                                         <= min(uba + E t', max(uba, A x_0, A x_A))}
                           t'_g = t*_g + LEAST_VIOLATION_MARGIN feas_tol where t*_g > 0 (else 0)

v_g is group g's largest violation at rest (its rows at x_0). (A) is always feasible (x_0 with t = v). Its last
rows say that no row ends worse than at rest by more than its group's worst comes back (v_g - t_g): a least-violation
tick never trades one fixture's excess for another's (without them, paper A's plate moved 10 mm gave a step that
took the shaft further off its curve to bring the tip nearer its own; with every row of a group allowed to its worst
at rest, the shaft's other facets went out 0.21 mm for the tip), while a group trades its own rows to bring its worst
back (with every row kept no worse than at rest, a tip 10 mm off its stays_at point along x and 20 mm along y, held
on a diagonal line, never moved: the x facet had to grow for the y facet to fall). They are the other sides of the
relaxed rows: (A) has 2m rows. S keeps every row no worse than at rest or at x_A: the levels take no row further
out than (A) did. Its measure sum_g (rho t_g / w_g + t_g^2/2) is strictly increasing and strictly convex in
t, so the least violation t* is unique. Each group's penalty is weighed against the group's own violation at rest: a
fixture a little off (a held one taken out by a step's second-order remainder) comes back first; with one weight for
all, a millimetre weighing as much as a radian, a port held within 0.5 mm was pushed 4.8 mm off while a cone 30 deg
away came back, each tick's remainder adding up (docs/runtime.md, Phase 2). With one group per row it sums over
rows; with coarser groups each group counts its worst row (an L-infinity measure inside one polytope). The linear
term makes the penalty exact at t = 0: a group that can be satisfied is satisfied exactly, since the tie-breaker mu
(smallest motion among least-violating points) has a marginal cost far below rho / w_g (such a group is off by at
most one tick's motion). The tie-breaker is mu I, not a multiple of H: H's eigenvalues span ~1e-6..10 on the example
tasks, and mu H / trace(H) next to the identity on t made (A) so ill-conditioned that CasADi's DAQP returned rows
violated by up to 2e-7 while reporting success; with mu I (A) is solved to ~1e-13 (measured).

(B) keeps every row of a satisfied group hard and lets each violated one go out by its group's least violation
(and the margin), no further than at rest or at x_A: x_A lies in S, the user's levels act only inside it, so no row that
could hold is traded for tracking, and the priorities stay lexicographic. S is a sliver (at the least violation the
relaxed rows nearly depend on the rows that stop them, the box at a speed limit), where DAQP's dual iterates failed
a level at most least-violation states of paper B; so (B) is solved from x_A by the primal active-set method of
:func:`vfdsl.runtime.lexls.from_feasible` (the generated C runs its twin), whose certified answer is the levels'
unique optimum over S, on both paths alike; where none is certified, x = x_A. (A) has n + G variables and 2m rows;
DAQP is dense, so G = m costs O((n + m)^3) per solve: pass coarse groups for large m (docs/runtime.md: timings).

(C) The step x (x_B, else x_A) is then taken only as far as the fixtures truly come back, their rows' bounds
evaluated where it ends (:mod:`vfdsl.runtime.line_search`): a x, a in {1, 1/2, ..., 1/32, 0}; without it a step
whose rows promised progress its second-order remainder took back made the joints alternate at their speed limits.

(A) is feasible by construction, so its answer is taken unless the solve failed outright (rows or
bounds off by more than 1e-6: a failed solve is off by orders of magnitude), clipped into B (the
solver's bound noise). If (B) fails, x is x_A, a least-violation move without the levels; if (A)
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

from vfdsl.codegen import tick_buffers
from vfdsl.codegen.solve_plan import PlannedFunction, SolvePlan, record
from vfdsl.runtime.daqp_solve import daqp_rows, daqp_solver
from vfdsl.runtime.line_search import SLOPE_STEP, group_worst, line_search, measure

QP_DATA_OUTPUTS = ("H", "g", "A", "lba", "uba", "lbx", "ubx")
GRADIENT_SATURATION = 1e3
"""K of :func:`_saturated_gradient`: a user push beyond K box widths is saturated."""
LEVEL_ATTEMPTS = ((1e-10, 1e-6), (1e-10, 1e-8), (1e-8, 1e-6))
"""(primal tolerance, rho) of the hierarchical solve, then of its retries on the ticks where the one before fails."""
LEVEL_ACCEPTANCE = 10.0
"""Phase 1 with priority levels is accepted when it meets the rows and bounds within LEVEL_ACCEPTANCE * feas_tol
(1e-8 m or rad per tick at vfdsl.compile's feas_tol): the last of LEVEL_ATTEMPTS runs at a primal tolerance of
1e-8."""
LEVEL_TIE_BREAK = 1e-6
"""epsilon: with ``last_level_is_cost``, DAQP's cost is the last level's (scaled to a unit largest diagonal) plus
epsilon I, positive definite also along the slacks, which damping does not weigh; it biases only that last level
(the smallest motion among the answers the levels above leave)."""
LEAST_VIOLATION_MARGIN = 10.0
"""The least-violation set of phase 2's (B) relaxes each violated row by its group's least violation and this many
feas_tol (LEVEL_ACCEPTANCE's: phase 1 accepts rows within as much): at the least violation the relaxed rows are
within ~1e-6 of the span of the rows that stop them (the box, at a speed limit), a vertex no working set of
independent rows describes; 1e-8 of room parts them."""
REST_VIOLATION_FLOOR = 1e-4
"""The least w_g of phase 2's (A) (m or rad): it bounds the weight rho / w_g of a group off by little or nothing at
rest (with 1e-6, DAQP failed (A) where two joints sat at their limits)."""
PER_ROW_GROUPS_LIMIT = 100
"""Above this many rows, one group per row makes phase 2 slow: a warning asks for groups."""


STRAIGHT_LINE_ENTRIES = 512
"""The step's solver-free parts are straight-line code when the general rows have at most this many entries."""


class StepStatus(enum.IntFlag):
    """What happened in one tick (the ``status`` output, as bit flags)."""

    OPTIMAL = 0
    LEAST_VIOLATION = 1  # phase 1 gave no feasible point: x solves the least-violation problem
    BOUNDS_CLIPPED = 2   # lbx > ubx somewhere (q outside its joint limits): bounds were clipped
    FALLBACK = 4         # the least-violation QP failed numerically: x is the zero motion clipped to B
    UNCERTIFIED = 8      # no certificate that x is the levels' optimum (lexls): phase 1's is DAQP's hierarchical
                         # answer, to its tolerance; a least-violation tick's is (A)'s x_A, without the levels


def build_step_function(qp_data: ca.Function, prefix: str, *,
                        row_groups: Sequence[Hashable] | None = None,
                        feas_tol: float = 1e-6,
                        penalty: float = 1.0,
                        tie_break: float = 1e-3, native: bool = False,
                        last_level_is_cost: bool = False, scope: str = "", backtrack: bool = True) -> PlannedFunction:
    """``prefix(q, u, p, dt, recover) -> (x[n], status, violation[m])`` solving ``qp_data``'s QP, with the solve
    plan of each of its DAQP conics (for the build).

    ``recover`` nonzero evaluates phase 2 even when phase 1 succeeds: the generated controller does
    it once when it is loaded, so that every solver's workspace exists before the first tick.

    ``row_groups[i]`` is the group of general row i (default: one group per row); ``feas_tol`` the
    absolute tolerance (row units) under which a row or bound counts as satisfied; ``penalty`` is
    rho and ``tie_break`` is mu of phase 2 (see the module docstring). ``native``: the Function is only for
    code generation (its DAQP solves are CasADi conics, which vfdsl.codegen.build compiles against DAQP's own
    sources); else CasADi evaluates it, DAQP solving through the ``daqp`` package. ``last_level_is_cost``: the last
    priority level (damping alone, positive definite on dq) is DAQP's own cost rather than a soft level (2.5 times
    faster on experiment B, measured with the daqp package: 7.3 against 18 us). ``scope`` starts the name of each
    of its solvers (unique in a step made of several, :func:`build_procedure_step`). ``backtrack``: phase 2's step
    goes only as far as it truly brings the rows back, their bounds evaluated where it ends
    (:mod:`vfdsl.runtime.line_search`), which presumes what the compiler's rows are, the fixtures linearized at q;
    False for a QP stated directly, whose bounds do not follow q so: the step is then taken whole.
    """
    levels = _check_qp_data(qp_data)
    n, m = qp_data.size1_out(0), qp_data.size1_out(2)
    procedure = qp_data.n_in() > len(tick_buffers.DATA_ARGUMENTS)
    arguments = tick_buffers.data_arguments(procedure)
    inputs = [ca.MX.sym(name, qp_data.sparsity_in(i)) for i, name in enumerate(arguments)]
    recover = ca.MX.sym("recover")
    expand = m * n <= STRAIGHT_LINE_ENTRIES
    if expand and qp_data.is_a("SXFunction"):   # with qp_data inside: its structural zeros prune the preparation
        prepared = _straight_line(              # (experiment B: 3,468 -> 1,674 operations)
            f"{prefix}_prepare", lambda *ins: _prepare(qp_data.call(list(ins)), levels, last_level_is_cost),
            inputs, expand)
    else:                                       # (an MX qp_data: e.g. a mesh fixture's external call in it)
        prepared = _straight_line(f"{prefix}_prepare", lambda *data: _prepare(data, levels, last_level_is_cost),
                                  qp_data.call(inputs), expand)
    A, lba, uba, lo, hi, clipped = prepared[:6]
    args = prepared[6:]     # the solve's H, g and rows (daqp_rows)
    plans: dict[str, SolvePlan] = {}
    sizes = [qp_data.size1_out(7 + 2 * j) for j in range(levels - last_level_is_cost)] if levels > 1 else []
    x1, uncertified = _solve_levels(args, recover, f"{scope}phase1", n=n, m=m, sizes=sizes, feas_tol=feas_tol,
                                    native=native, plans=plans)

    if m == 0:
        picked = ca.vertcat(x1, int(StepStatus.UNCERTIFIED) * uncertified)
    else:
        accept_tol = feas_tol * (LEVEL_ACCEPTANCE if levels > 1 else 1)
        ok1 = _straight_line(f"{prefix}_accept", lambda x, A, *box: [_acceptable(x, A @ x, *box, accept_tol)],
                             [x1, A, lba, uba, lo, hi], expand)
        solve_from = daqp_solver(n, m, feas_tol * 1e-3, f"{scope}phase2b", native, plans, sizes, start=True)
        E = _incidence(m, row_groups)
        search = line_search(qp_data, inputs, E, feas_tol, penalty, f"{prefix}_search") if backtrack else None
        switch = _phase2_switch([A, lba, uba, lo, hi, x1, uncertified, recover, *args, *inputs], E, feas_tol,
                                penalty, tie_break, solve_from, search, accept_tol, native, plans, scope)
        picked = switch(ca.logic_and(ok1, recover == 0), A, lba, uba, lo, hi, x1, uncertified, recover, *args,
                        *inputs)
    x, status, violation = _straight_line(f"{prefix}_finish", lambda *v: _finish(*v, m, feas_tol),
                                          [picked, A, lba, uba, lo, hi, clipped], expand)
    return PlannedFunction(ca.Function(prefix, [*inputs, recover], [x, status, violation],
                                       list(tick_buffers.arguments(procedure)), list(tick_buffers.RESULTS)), plans)


def build_procedure_step(cases: Sequence[tuple[ca.Function, Sequence[int], bool]], choose: Callable[[ca.MX], ca.MX],
                         m: int, prefix: str, *, row_groups: Sequence[Hashable] | None = None,
                         **options) -> PlannedFunction:
    """A procedure's step, ``prefix(q, u, p, dt, activity, recover) -> (x, status, violation[m])``, made of one step
    per case (:func:`build_step_function` of each case's QP data, row indices and last_level_is_cost,
    :mod:`vfdsl.compiler.cases`), of which ``choose(activity)`` picks one each tick: a switch, so only that case is
    evaluated and solved, each case's solvers keeping their own workspace and warm start (a case's first tick is its
    priming's, see Controller._prime). The violation of a row the case leaves out is 0 (its bounds are infinite
    there)."""
    steps, plans = [], {}
    for k, (qp_data, rows, last_level_is_cost) in enumerate(cases):
        groups = None if row_groups is None else [row_groups[i] for i in rows]
        step = build_step_function(qp_data, f"{prefix}_case{k}", row_groups=groups, scope=f"case{k}_",
                                   last_level_is_cost=last_level_is_cost, **options)
        for name, plan in step.plans.items():
            record(plans, name, plan)
        symbols = step.mx_in()
        x, status, violation = step(*symbols)
        full = ca.MX.zeros(m) if m else ca.MX(0, 1)
        if rows:
            full[list(rows)] = violation
        steps.append(ca.Function(f"{prefix}_case{k}_rows", symbols, [x, status, full], step.name_in(),
                                 step.name_out()))
    inputs = steps[0].mx_in()
    case = choose(inputs[steps[0].index_in(tick_buffers.PHASE_ARGUMENTS[0])])
    chosen = ca.Function.conditional(f"{prefix}_cases", steps, steps[-1])(case, *inputs)
    return PlannedFunction(ca.Function(prefix, inputs, chosen, steps[0].name_in(), steps[0].name_out()), plans)


def _solve_levels(args: list[ca.MX], recover: ca.MX, name: str, *, n: int, m: int, sizes: Sequence[int],
                  feas_tol: float, native: bool, plans: dict[str, SolvePlan]) -> tuple[ca.MX, ca.MX]:
    """(x, uncertified) of the levels over the hard rows: with priority levels (``sizes``: each level's row count),
    DAQP's hierarchical solve, exact where certified (uncertified 0, else 1), retried with each of LEVEL_ATTEMPTS
    where the one before fails; else one QP warm-started from the previous call's working set (uncertified 0: no
    levels). ``args``: [H, g, a, lower, upper] (daqp_rows)."""
    if not sizes:
        return daqp_solver(n, m, feas_tol * 1e-3, f"{name}_warm", native, plans, warm_start=True)(*args), ca.MX(0)
    answer = None
    for k, (tol, rho) in enumerate(LEVEL_ATTEMPTS):
        solve = daqp_solver(n, m, tol, f"{name}_try{k}", native, plans, sizes, rho,
                            partial=k == len(LEVEL_ATTEMPTS) - 1, exact=True)
        answer = solve(*args) if answer is None else _retried(answer, recover, solve, args)
    return answer[:n], answer[n]


def _straight_line(name: str, build: Callable[..., list[ca.MX]], values: Sequence[ca.MX], expand: bool):
    """build's outputs on ``values``, through a Function ``name`` of symbols shaped like them: a part of the step
    without a solver. ``expand``: the Function expanded to scalar operations, generated as straight-line C
    (:data:`STRAIGHT_LINE_ENTRIES`), where the MX graph's ~300 small loops (7 or 49 entries each) took most of
    experiment B's tick outside its solve (measured: qp_data 0.23 us, the rest of the graph around the solve about
    1 us, 0.6 us expanded)."""
    symbols = [ca.MX.sym(f"{name}_{k}", v.sparsity()) for k, v in enumerate(values)]
    function = ca.Function(name, symbols, list(build(*symbols)))
    return (function.expand() if expand else function)(*values)


def _prepare(data: Sequence[ca.MX], levels: int, last_level_is_cost: bool) -> list[ca.MX]:
    """From qp_data's outputs: [A, lba, uba, lo, hi, clipped] of the QP (the box made safe), then the solve's
    [H, g, a, lower, upper] (g saturated) (:func:`~vfdsl.runtime.daqp_solve.daqp_rows`): with priority levels,
    DAQP's cost and the levels' rows and targets (each level scaled) after the rows and the box."""
    data = [ca.densify(v) for v in data]
    n = data[0].size1()
    H, g, A, lba, uba, lbx, ubx = data[:7]
    lo, hi, clipped = _safe_box(lbx, ubx)
    prepared = [A, lba, uba, lo, hi, clipped]
    if levels > 1:
        pairs = list(zip(data[7::2], data[8::2]))
        if last_level_is_cost:      # DAQP's own cost: the last level, + epsilon I
            R_k, r_k = pairs.pop()
            H_k = R_k.T @ R_k
            scale = _unit_diagonal(H_k)
            H_cost = scale * H_k + LEVEL_TIE_BREAK * ca.MX.eye(n)
            g_cost = _saturated_gradient(H_cost, -scale * (R_k.T @ r_k), lo, hi)
        else:                       # DAQP's own cost: the tie-break |x|^2 / 2
            H_cost, g_cost = ca.MX(ca.DM.eye(n)), ca.MX(ca.DM.zeros(n))
        rows = [_level_rows(R, r, lo, hi) for R, r in pairs]
        R, r = ca.vertcat(*(R for R, _ in rows)), ca.vertcat(*(r for _, r in rows))
        return prepared + [H_cost, g_cost, *daqp_rows(A, lba, uba, lo, hi, R, r)]
    return prepared + [H, _saturated_gradient(H, g, lo, hi), *daqp_rows(A, lba, uba, lo, hi)]


def _finish(picked, A, lba, uba, lo, hi, clipped, m: int, feas_tol: float) -> list[ca.MX]:
    """(x, status, violation) from the picked [x; status]. The last line of defence, for every path: x is finite
    and in B (up to the solver's bound noise, then clipped), or it is the rest motion with FALLBACK. A row whose
    bounds are not numbers (NaN: a fixture's direction from captures that coincide, :meth:`Context.derived`) is
    undefined, not absent (the solvers read a NaN bound as none): the tick is the rest motion with FALLBACK, and the
    row's violation is inf, so ``violations()`` names it."""
    n = lo.size1()
    x, status = picked[:n], picked[n]
    undefined = _undefined_rows(lba, uba)
    safe = _in_box(x, lo, hi, _GROSS_FAILURE)
    if m:
        safe = ca.logic_and(safe, ca.mmax(undefined) == 0)
    x = ca.if_else(safe, _clip(x, lo, hi), _rest(lo, hi))
    status = ca.if_else(safe, status, int(StepStatus.LEAST_VIOLATION) * (m > 0) + int(StepStatus.FALLBACK))
    status = status + int(StepStatus.BOUNDS_CLIPPED) * clipped
    violation = _row_violation(A @ x, lba, uba)
    return [x, status, ca.if_else(undefined, ca.inf, ca.if_else(violation > feas_tol, violation, 0))]


def _undefined_rows(lba, uba) -> ca.MX:
    """1 for each row with a NaN bound (every comparison with NaN is false). A fixture's undefined geometry is in its
    rows' bounds, its error (a NaN in a row's entries alone would fail the solve: the rest motion with FALLBACK)."""
    return 1 - ca.logic_and(lba <= ca.inf, uba >= -ca.inf)


def _check_qp_data(qp_data: ca.Function) -> int:
    """The number of priority levels: 1 for the 7 outputs of QP_DATA_OUTPUTS, k >= 2 for 7 + 2k outputs
    (Rj, rj per level); the arguments are the tick's data buffers (a procedure's with its activity)."""
    n_out = qp_data.n_out()
    levels = 1 if n_out == 7 else (n_out - 7) // 2
    arguments = tick_buffers.DATA_ARGUMENTS
    counts = (len(arguments), len(tick_buffers.data_arguments(procedure=True)))
    if qp_data.n_in() not in counts or n_out < 7 or (n_out != 7 and (levels < 2 or 7 + 2 * levels != n_out)):
        raise ValueError(f"qp_data must map ({', '.join(arguments)}) (a procedure's: then "
                         f"{', '.join(tick_buffers.PHASE_ARGUMENTS)}) to {QP_DATA_OUTPUTS} (+ Rj, rj per priority "
                         f"level), got {qp_data.n_in()} inputs and {n_out} outputs")
    n, m = qp_data.size1_out(0), qp_data.size1_out(2)
    expected = [(n, n), (n, 1), (m, n), (m, 1), (m, 1), (n, 1), (n, 1)]
    if levels > 1:
        for j in range(levels):
            expected += [(qp_data.size1_out(7 + 2 * j), n), (qp_data.size1_out(7 + 2 * j), 1)]
    got = [(qp_data.size1_out(i), qp_data.size2_out(i)) for i in range(n_out)]
    if got != expected:
        raise ValueError(f"qp_data output shapes {got} do not match {expected} for n={n}, m={m}")
    return levels


def _level_rows(R: ca.MX, r: ca.MX, lo: ca.MX, hi: ca.MX) -> tuple[ca.MX, ca.MX]:
    """One level's rows and targets scaled to a longest row of 1 (no minimizer of the level changes: DAQP's data
    stay O(1) whatever the weights), the targets then saturated as :func:`_saturated_gradient` saturates g: a
    target beyond K sqrt(n) W of zero cannot be met inside the box B (|R x|_inf <= |x|_2 <= sqrt(n) W)."""
    scale = _unit_rows(R)
    R, r = R * scale, r * scale
    limit = GRADIENT_SATURATION * np.sqrt(R.size2()) * _box_width(lo, hi)
    r_max = ca.mmax(ca.fabs(r))
    return R, r * ca.if_else(ca.logic_and(limit > 0, r_max > limit), limit / r_max, 1)


def _unit_rows(R: ca.MX) -> ca.MX:
    """The factor that scales the rows R to a longest row of 1 (1 when R is zero)."""
    longest = ca.sqrt(ca.mmax(ca.sum2(R * R)))
    return ca.if_else(longest > 0, 1 / longest, 1)


def _unit_diagonal(H: ca.MX) -> ca.MX:
    """The factor that scales the Hessian H to a largest diagonal entry of 1."""
    return 1 / ca.fmax(ca.mmax(ca.diag(H)), 1e-300)


def _retried(x: ca.MX, recover: ca.MX, again: Callable[..., ca.MX], args: list) -> ca.MX:
    """x (a solve's answer: [x; uncertified]), or ``again(*args)`` when x is not finite (a failed solve) or
    ``recover`` is nonzero (the priming tick,
    which so sets up the retry's solver too): a switch between Functions, so the second solve runs only on the
    ticks that need it."""
    symbols = [ca.MX.sym(f"a{k}", v.sparsity()) for k, v in enumerate([x, *args])]
    keep = ca.Function("keep_first", symbols, [symbols[0]])
    retry = ca.Function("solve_again", symbols, [again(*symbols[1:])])
    use_first = ca.logic_and(ca.mmin(ca.fabs(x) < ca.inf), recover == 0)
    return ca.Function.if_else("retry_if_failed", keep, retry)(use_first, x, *args)


def _box_width(lo: ca.MX, hi: ca.MX) -> ca.MX:
    """W: the largest finite bound of the box, in magnitude (0 when none is finite)."""
    finite_abs = lambda b: ca.if_else(ca.fabs(b) < ca.inf, ca.fabs(b), 0)  # noqa: E731
    return ca.mmax(ca.fmax(finite_abs(lo), finite_abs(hi)))


def _saturated_gradient(H: ca.MX, g: ca.MX, lo: ca.MX, hi: ca.MX) -> ca.MX:
    """g, scaled down (never up) so that |g|_inf <= K ||H||_inf W, W the largest finite bound of B.

    ||H||_inf >= lambda_max(H), so an unscaled |g|_inf above that limit puts the unconstrained step
    -H^-1 g at least K W from the origin: the answer is saturated by the bounds either way, and the
    scaled g keeps its direction while DAQP's transformed data (R^-T g, A H^-1 g) stay far from
    overflow and from swamping the rows' offsets. Never active on the example tasks' normal ticks."""
    width = _box_width(lo, hi)
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


def _phase2_switch(values: list[ca.MX], E: ca.DM, tol, rho, mu, solve_from, search, accept_tol, native, plans,
                   scope: str) -> ca.Function:
    """switch(ok, A, lba, uba, lo, hi, x1, uncertified, recover, *args, *data) -> [x1; status] when ok (phase 1's
    answer: OPTIMAL, or UNCERTIFIED where phase 1's ``uncertified`` is 1), else phase 2's [x; status] (args: phase 1's
    solve, [H, g, a, lower, upper]; data: the step's data arguments, q first; ``solve_from``: (B)'s solve, from a
    point; ``search``: the step's length, :func:`~vfdsl.runtime.line_search.line_search`; ``recover``: the priming
    tick).

    The branches are Functions of values already computed: a short-circuit ``if_else`` on
    expressions would make each branch recompute them (QP data and phase 1) from the inputs.
    """
    names = ("A", "lba", "uba", "lo", "hi", "x1", "uncertified", "recover", "H_s", "g_s", "a_s", "lower_s", "upper_s")
    names += tuple(f"data{k}" for k in range(len(values) - len(names)))
    args = [ca.MX.sym(name, v.sparsity()) for name, v in zip(names, values)]
    x1, uncertified = args[5], args[6]
    keep = ca.Function("keep", args, [ca.vertcat(x1, int(StepStatus.UNCERTIFIED) * uncertified)])
    recover = ca.Function("recover", args, [_least_violation(*args[:5], args[8:13], args[13:], E, tol, rho, mu,
                                                             solve_from, search, accept_tol, native, plans, scope,
                                                             args[7])])
    return ca.Function.if_else("phase2_if_needed", keep, recover)


# (A) is feasible by construction; its check only has to catch a failed solve, whose answer is off by orders of
# magnitude (seen: 1 to 20), not decide feasibility at the 1e-9 level, where the generated and interpreted
# evaluations (whose QP data differ in the last bits) could decide differently.
_GROSS_FAILURE = 1e-6


def _least_violation(A, lba, uba, lo, hi, solve_args, data, E: ca.DM, tol, rho, mu, solve_from, search, accept_tol,
                     native, plans, scope: str, recover: ca.MX) -> ca.MX:
    """Phase 2 (A then B, then the step's length), returning [x; status]. (A) is solved at primal tolerance 1e-3
    tol, and where DAQP fails there, once more at tol (seen: a weighted (A) that DAQP called infeasible at 1e-12 and
    solved at 1e-9)."""
    n, m, G = lo.size1(), A.size1(), E.size2()
    x_0 = _rest(lo, hi)
    at_rest = A @ x_0
    v = _rest_violations(E, lba, uba, at_rest)
    w = ca.fmax(v, REST_VIOLATION_FLOOR)
    H_a = ca.diagcat(mu * ca.DM.eye(n), ca.DM.eye(G))
    g_a = ca.vertcat(ca.DM.zeros(n), rho / w)
    A_a = ca.vertcat(ca.horzcat(A, E), ca.horzcat(A, -E))
    # each row's other side: no worse than at rest, but by what its group's worst comes back (v_g - t_g)
    lba_a = ca.vertcat(lba, ca.fmin(lba, at_rest) - E @ v)
    uba_a = ca.vertcat(ca.fmax(uba, at_rest) + E @ v, uba)
    lbz, ubz = ca.vertcat(lo, ca.DM.zeros(G)), ca.vertcat(hi, ca.inf * ca.DM.ones(G))
    rows_a = [H_a, g_a, *daqp_rows(A_a, lba_a, uba_a, lbz, ubz)]
    z = _retried(daqp_solver(n + G, 2 * m, tol * 1e-3, f"{scope}phase2a", native, plans)(*rows_a), recover,
                 daqp_solver(n + G, 2 * m, tol, f"{scope}phase2a_again", native, plans), rows_a)
    # Acceptance is decided on the solver's own answer, before any clipping: clipping a failed solve's NaN into B
    # would turn it into a full-speed motion that looks feasible.
    ok_a = _acceptable(z, A_a @ z, lba_a, uba_a, lbz, ubz, _GROSS_FAILURE)
    x_a = _clip(z[:n], lo, hi)      # used only when (A) is acceptable, i.e. z is finite
    kept = ca.if_else(ok_a, A @ x_a, at_rest)       # rows (A) took out beyond their rest value, to bring its group back
    lower, upper = _least_violation_set(lba, uba, ca.fmin(at_rest, kept), ca.fmax(at_rest, kept),
                                        E @ ca.if_else(ok_a, ca.fmax(z[n:], 0), 0), tol)
    H_s, g_s, a_s, lower_s, upper_s = solve_args
    answer = solve_from(H_s, g_s, a_s, ca.vertcat(lower, lower_s[m:]), ca.vertcat(upper, upper_s[m:]), x_a)
    x_b = answer[:n]
    ok_b = _acceptable(x_b, A @ x_b, lower, upper, lo, hi, accept_tol)
    x = ca.if_else(ok_a, ca.if_else(ok_b, _clip(x_b, lo, hi), x_a), x_0)
    x = x_0 + _step_length(A, lba, uba, at_rest, x_0, x, data, E, v, w, tol, rho, search,
                           ca.logic_not(ok_a)) * (x - x_0)
    uncertified = ca.if_else(ok_a, ca.if_else(ok_b, answer[n], 1), 0)     # (A) failed: FALLBACK says it
    status = (int(StepStatus.LEAST_VIOLATION) + int(StepStatus.FALLBACK) * (1 - ok_a)
              + int(StepStatus.UNCERTIFIED) * uncertified)
    return ca.vertcat(x, status)


def _rest_violations(E: ca.DM, lba, uba, at_rest) -> ca.MX:
    """v_g: the largest violation at rest of group g's rows (0 for a group that holds at rest)."""
    return group_worst(E, _row_violation(at_rest, lba, uba))


def _step_length(A, lba, uba, at_rest, x_0, x, data, E: ca.DM, v, w, tol, rho, search, failed) -> ca.MX:
    """a in [0, 1]: how far along x_0 -> x phase 2's step goes (:mod:`vfdsl.runtime.line_search`), its measure
    counting the hard rows (no slack column) of the groups off at rest (v_g > tol); 1 where (A) ``failed`` (x is
    x_0), where the box forces a motion (x_0 != 0) and where no hard group is off at rest. ``at_rest`` = A x_0, the
    rows at rest wherever the search runs (x_0 = 0)."""
    if search is None:
        return ca.MX(1)
    nq = data[0].size1()
    hard = ca.sum2(ca.fabs(A[:, nq:])) == 0 if A.size2() > nq else ca.MX.ones(A.size1())    # no slack column
    counted = hard * (E @ (v > tol))

    def phi(moved):     # the measure of the rows at A dq = ``moved``
        return measure(E, _row_violation(moved, lba, uba), counted, w, tol, rho)

    phi_0 = phi(at_rest)
    predicted = (phi(at_rest + A @ (SLOPE_STEP * x)) - phi_0) / SLOPE_STEP       # the rows' slope along x
    whole = ca.Function("whole_step", search.mx_in(), [ca.MX(1)])
    skip = ca.logic_or(ca.logic_or(failed, ca.mmax(ca.fabs(x_0)) > 0), phi_0 == 0)
    return ca.Function.if_else("search_if_off", whole, search)(skip, *data, x, w, counted, phi_0, predicted)


def _least_violation_set(lba, uba, low, high, relaxed, tol) -> tuple[ca.MX, ca.MX]:
    """The rows' bounds of the least-violation set S: each row of a violated group (``relaxed``: E t*, above
    1e-3 tol) relaxed by the group's least violation and LEAST_VIOLATION_MARGIN tol, and no row worse than both at
    rest and at (A)'s answer (``low``, ``high``: the lesser and the greater of A x_0 and A x_A)."""
    widened = ca.if_else(relaxed > 1e-3 * tol, relaxed + LEAST_VIOLATION_MARGIN * tol, 0)
    return ca.fmax(lba - widened, ca.fmin(lba, low)), ca.fmin(uba + widened, ca.fmax(uba, high))
