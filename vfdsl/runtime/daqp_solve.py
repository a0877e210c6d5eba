"""One dense DAQP solve inside the tick's graph (:mod:`vfdsl.runtime.qp` makes every solve of a tick here).

:func:`daqp_solver` gives the solve as a CasADi conic, which the generated C evaluates with DAQP's own sources, or
as the same problem, settings and rows through the ``daqp`` package (:func:`solve_daqp`) for CasADi's evaluation;
either way it records the conic's :class:`~vfdsl.codegen.solve_plan.SolvePlan` (warm start, priority levels, exact
solve of the levels), which the build applies to the generated conic. :func:`daqp_rows` stacks DAQP's rows: the
general rows, the box as identity rows, then the levels' rows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from vfdsl.codegen import solve_plan
from vfdsl.codegen.solve_plan import SolvePlan, record
from vfdsl.runtime import lexls

MAX_LEVELS = 15
"""Priority levels one solve takes (VFDSL_LEVELS_MAX - 1 in daqp_persistent.c; a task has at most 5 priorities, each
at most 2 levels: a track term's two parts)."""


def daqp_solver(n: int, m: int, primal_tol: float, name: str, native: bool, plans: dict[str, SolvePlan],
                level_rows: Sequence[int] = (), rho: float = 1e-8, partial: bool = False,
                exact: bool = False, warm_start: bool = False, start: bool = False) -> Callable[..., ca.MX]:
    """solve(H, g, *daqp_rows(A, lba, uba, lbx, ubx[, R, r[, r_upper]])) -> x: one dense DAQP solve, x = NaN when
    it fails.
    ``primal_tol``: DAQP's (1e-3 feas_tol for the solves without levels, :data:`vfdsl.runtime.qp.LEVEL_ATTEMPTS`
    with them).

    The variable bounds reach DAQP as identity rows (through CasADi's conic interface DAQP met simple bounds only
    to ~5e-8, measured). With ``level_rows`` (the row count of each priority level), R stacks the levels' rows and
    r their targets (or r <= R x <= r_upper): DAQP's hierarchical mode minimizes || R_1 x - r_1 ||^2 (the rows'
    squared violations) over the rows and bounds, then each
    level in turn over the optimal set of the levels above, and the QP's own cost last, every soft row weighted
    by ``rho`` (:data:`vfdsl.runtime.qp.LEVEL_ATTEMPTS`). ``partial``: when DAQP fails a level, x is its answer for
    the levels above it (which meets the rows and bounds) instead of NaN.
    ``exact``: the levels' targets are equalities (phase 1), so their exact solve (:mod:`vfdsl.runtime.lexls`)
    replaces DAQP's answer where it is certified; solve(...) then gives [x; uncertified], the last entry 0 where x
    is certified the levels' optimum, 1 where it is DAQP's answer (NaN with x). The conic's cost output carries
    it: an exact plan's conic has no other use for its cost.
    ``warm_start``: the generated C starts DAQP from the previous call's working set.
    ``start``: solve(..., x0): the levels (or the one cost) solved exactly from x0, a point of the rows and bounds,
    by :func:`vfdsl.runtime.lexls.from_feasible` (and its C twin), DAQP not called; x0 itself where no answer is
    certified (the method's iterates there depend on the last bits of the data, which the paths do not share), and
    [x; uncertified] as with ``exact``.
    ``native``: a CasADi conic, which only the generated C evaluates (vfdsl.codegen.build puts DAQP's own sources
    behind it, solving as the conic's plan in ``plans`` says); else the same solver, settings and rows through
    the ``daqp`` package (:class:`_DaqpNode`), for CasADi's evaluation."""
    free = ca.inf * ca.DM.ones(n)
    extra = sum(level_rows)
    breaks = [int(b) for b in np.cumsum([2 * n + m, *level_rows])] if level_rows or start else []
    if len(breaks) > MAX_LEVELS + 1:
        raise ValueError(f"{len(level_rows)} priority levels; the generated solver takes at most {MAX_LEVELS}")
    if start:
        plan = SolvePlan(break_points=tuple(breaks), exact=True, start=True)
    else:
        plan = SolvePlan(warm_start, tuple(breaks), rho, partial, exact) if breaks else SolvePlan(warm_start)
    record(plans, name, plan)
    if native:
        sparsity = {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity.dense(m + n + extra, n)}
        options = {"error_on_fail": False, "daqp": {"primal_tol": primal_tol}}
        conic = ca.conic(name, "daqp", sparsity, options)
    else:
        conic = _DaqpNode.function(name, n, m + n + extra, primal_tol, plan)

    def solve(H, g, a, lower, upper, x0=None):
        initial = {} if x0 is None else {"x0": x0}
        out = conic(h=H, g=g, a=a, lba=lower, uba=upper, lbx=-free, ubx=free, **initial)
        return ca.vertcat(out["x"], out["cost"]) if plan.exact else out["x"]

    return solve


def daqp_rows(A, lba, uba, lbx, ubx, R=None, r=None, r_upper=None):
    """(a, lower, upper): DAQP's rows (:func:`daqp_solver`), the general rows, the box as identity rows, then the
    levels' rows R with targets r (or r <= R x <= r_upper)."""
    rows, lower, upper = [A, ca.DM.eye(A.size2())], [lba, lbx], [uba, ubx]
    if R is not None:
        rows, lower, upper = [*rows, R], [*lower, r], [*upper, r if r_upper is None else r_upper]
    return ca.densify(ca.vertcat(*rows)), ca.vertcat(*lower), ca.vertcat(*upper)


class _DaqpNode(ca.Callback):
    """(h, g, a, lba, uba, lbx, ubx) -> (x, cost): the generated conic's DAQP solve, cold, through the ``daqp``
    package (the same DAQP version the generated C is built from): the same problem (bounds as simple bounds, rows
    with lba = uba as equalities), tolerance and settings; x = NaN unless DAQP reports success. The plan's ``exact``:
    DAQP's answer solved again exactly over the rows it holds, taken when certified
    (:func:`vfdsl.runtime.lexls.polish`), and the cost output is the certificate, as the generated conic's
    (:func:`daqp_solver`)."""

    _alive: dict = {}        # CasADi holds a Callback by reference: each node lives as long as the process; nodes
    # hold no state between calls, so one node serves every graph that needs its problem (bounded by their kinds)

    @classmethod
    def function(cls, name: str, n: int, rows: int, primal_tol: float, plan: SolvePlan) -> ca.Function:
        key = (name, n, rows, primal_tol, plan)
        if key not in cls._alive:
            cls._alive[key] = cls(name, n, rows, primal_tol, plan)
        return cls._alive[key]

    def __init__(self, name: str, n: int, rows: int, primal_tol: float, plan: SolvePlan):
        ca.Callback.__init__(self)
        self.n, self.rows, self.primal_tol = n, rows, primal_tol
        self.break_points, self.rho = list(plan.break_points), plan.rho
        self.exact, self.start = plan.exact, plan.start
        self.success = DAQP_SUCCESS + (DAQP_PARTIAL,) * plan.partial
        self.construct(name, {})

    def get_n_in(self):
        return 8 if self.start else 7

    def get_n_out(self):
        return 2

    def get_name_in(self, i):
        return ("h", "g", "a", "lba", "uba", "lbx", "ubx", "x0")[i]

    def get_name_out(self, i):
        return ("x", "cost")[i]

    def get_sparsity_in(self, i):
        n, rows = self.n, self.rows
        return ca.Sparsity.dense(*((n, n), (n, 1), (rows, n), (rows, 1), (rows, 1), (n, 1), (n, 1), (n, 1))[i])

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(self.n if i == 0 else 1, 1)

    def eval(self, arg):
        H, g, A, lba, uba, lbx, ubx = (np.array(a, dtype=float) for a in arg[:7])
        g = g.ravel()
        lower, upper = np.concatenate((lbx.ravel(), lba.ravel())), np.concatenate((ubx.ravel(), uba.ravel()))
        if self.start:      # from x0, a point of the rows and bounds, without DAQP
            H, f, A_hard, lo, up, levels = lexls.split(H, g, A, lower, upper, self.break_points)
            x0 = np.array(arg[7], dtype=float).ravel()
            x, certified = lexls.from_feasible(H, f, A_hard, lo, up, levels, x0)
            return [x, 0.0] if certified else [x0, 1.0]
        x, flag, *_ = solve_daqp(H, g, A, lower, upper, self.primal_tol, self.break_points, self.rho)
        if flag not in self.success:
            return [np.full(self.n, np.nan), np.nan]
        if self.exact:      # the levels solved exactly over the rows DAQP's answer holds, when certified
            x_exact, certified = lexls.polish(H, g, A, lower, upper, self.break_points, x)
            return [x_exact, 0.0] if certified else [x, 1.0]
        return [x, 0.5 * x @ H @ x + g @ x]


DAQP_SUCCESS = (1, 2)
"""DAQP's exit flags of an answer: optimal; with levels also soft-optimal, its normal success; as in
daqp_persistent.c."""
DAQP_PARTIAL = 3
"""DAQP's exit flag when it failed a level: x is the answer of the levels above (taken by the last attempt)."""


def solve_daqp(H, g, A, lower, upper, primal_tol, break_points=(), rho_soft=0.0):
    """(x, exit flag, iterations, seconds: DAQP's own solve time) of DAQP on min 1/2 x'Hx + g'x, lower <= [x; A x] <= upper (the first n entries
    simple bounds), rows with lower = upper equalities; with ``break_points``, DAQP's priority levels, the rows past
    the first break point soft with weight ``rho_soft`` in the problem's own scale. At most ITER_LIMIT iterations
    (codegen.solve_plan: the generated C's limit too); reaching it is a failed solve (exit flag -4)."""
    import daqp
    n = H.shape[0]
    sense = np.where(lower == upper, 5, 0).astype(np.intc)      # DAQP_ACTIVE + DAQP_IMMUTABLE
    model = daqp.Model()
    setup, _ = model.setup(np.ascontiguousarray(H), np.ascontiguousarray(g), np.ascontiguousarray(A.reshape(-1, n)),
                np.ascontiguousarray(upper), np.ascontiguousarray(lower), sense,
                np.asarray(break_points, dtype=np.intc) if len(break_points) else None)
    if setup < 0:       # (e.g. a non-finite H or rows)
        return np.full(n, np.nan), setup, 0, 0.0
    model.settings = {"primal_tol": primal_tol, "eq_reduction": -1, "iter_limit": solve_plan.ITER_LIMIT}
    if len(break_points):
        rho = np.r_[np.zeros(break_points[0]), np.full(len(lower) - break_points[0], rho_soft)]
        model.soft_weights(rho_l=rho, rho_u=rho)
    x, _, flag, info = model.solve()
    return np.array(x), int(flag), int(info["iterations"]), float(info["solve_time"])
