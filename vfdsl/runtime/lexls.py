"""Priority levels solved exactly over a working set, and a certificate that the answer is the levels' optimum.

The problem of a tick with priority levels (:mod:`vfdsl.runtime.qp`), over x in R^n:

    hard:       lo_i <= a_i'x <= up_i,   i = 1..K          (the task's rows, then the box as identity rows)
    level j:    minimize 1/2 |R_j x - r_j|^2   over the hard rows and the optimal set of every level above
    last:       minimize 1/2 x'Hx + f'x        over the optimal set of every level   (H positive definite)

Its answer x* is unique. A *working set* W says which hard rows hold x at a bound: ``s_i`` = +1 (upper), -1
(lower), 2 (lo_i = up_i, always held), 0 (free). :func:`solve_over` computes the levels' optimum with W's rows
as equalities and the other hard rows left out, by least squares in nested null spaces:

    x = 0, Z = I;  for (M, t) in [(C_W, d_W), (R_1, r_1), ..., (R_L, r_L)]:
        y = argmin |M Z y - (t - M x)|,  x += Z y,  Z = Z N   (N: orthonormal null space of M Z)
    x += Z y,  y = -(Z'HZ)^-1 Z'(Hx + f)

(rank by pivoted QR, a column counting when its pivot exceeds ``RANK_TOL``; every hard row is scaled to unit
length first, which moves none of its bounds' points), and then *certifies* it:

- **primal**: every hard row holds within ``PRIMAL_TOL``, and W's rows are met (C_W x = d_W; an inconsistent
  guess is not);
- **dual**, for each level j and the last cost: its gradient G_j at x is a combination of the rows of the levels
  above (any sign), of W's equality rows (any sign) and of W's inequality rows each with the sign of the bound
  that holds x back: G_j + sum_{i<j} R_i'mu_i + C_eq'nu + sum_{i in W_in} lambda_i s_i a_i = 0 with lambda >= 0.
  With U_j spanning the null space of C_eq and of the levels above, that is: the nonnegative least squares
  min_{lambda >= 0} |U_j'(G_j + C_in' S lambda)| is zero (within ``DUAL_TOL`` |G_j|, the residual charged its
  rounding: :data:`ROUNDING`).

The certificate is the KKT conditions of level j over the hard rows and the optimal sets of the levels above
(the minimizers of |R_i x - r_i|^2 over a convex set share R_i x, so that set is the hard rows and R_i x = R_i x*
for i < j): sufficient, the problems being convex. So a certified x is x*, whatever W it came from; W decides only
whether a certificate is found (it is when W holds the rows active at x* with a positive multiplier at some level
and no other row that the levels would leave). The generated C (``vfdsl/codegen/lexls.c``) runs the same steps
with its own Householder QR, Cholesky and Lawson-Hanson NNLS; this module, the interpreted path's, uses LAPACK's
(through scipy) and the same NNLS (:func:`_nnls_within`). No library offers the lexicographic solve over a working
set with this certificate (DAQP's hierarchical mode, which both paths call when no certificate is found, holds each
level to its tolerance, not exactly); the C is ours because the generated tick links no LAPACK.

Two cheaper sufficient tests run first at each level (:func:`_factors_dual`: multipliers from the solve's own
factors; :func:`_dims_dual`: when the fixed rows and the levels above cut as many dimensions as the solve's steps
up to that level did, U_j is the solve's null space, where G_j is zero by construction); the nonnegative least
squares, and the chain of U_j it needs, only where neither certifies the level.

:func:`from_feasible` reaches the optimum from a point of the hard rows by a primal active-set method over these
solves and certificates (phase 2's (B), whose feasible set is a sliver around that point).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

RANK_TOL = 1e-10
"""A pivot of the QR of (M Z)' counts toward its rank when larger than this (rows of unit length at most, Z
orthonormal)."""
COND_TOL = 1e-4
"""A pivot between RANK_TOL and COND_TOL makes the answer ill-conditioned (a direction pinned by rows that nearly
depend on others: moving the rows by 1e-10 would move x by 1e-6 or more), and it is not certified as it stands. In
W's own rows it is a degenerate vertex (:func:`_degenerate`). Measured at 100 random states of every example task:
kept pivots are >= 0.047 everywhere but on paper_a_follow_curve, where the tip's and the shaft's facets at the same
corner of their octagons give 2e-7 to 1.5e-6; solved with all of them held, the answer there was up to 100x worse on
the second level than DAQP's."""
PRIMAL_TOL = 1e-9
"""Every hard row (unit length) must hold within this, and W's rows be met within it (m or rad per tick; phase 1 is
accepted within 1e-8, vfdsl.runtime.qp.LEVEL_ACCEPTANCE). At 1e-10, four facets of a 31 x 31 stays_at polytope
meeting at a vertex (four rows in the tip's three dimensions) were inconsistent by ~1e-10 at 16 of 60 states."""
DUAL_TOL = 1e-9
"""A level is certified when its multipliers' least squares leave a residual below DUAL_TOL times the scale of its
gradient: |R_j|_F (|R_j|_F |x| + |r_j|) for a level, |H|_F |x| + |f| for the last cost (bounds of |G_j|, so that a
level met to rounding, G_j ~ 1e-20, is certified)."""
DEGENERATE_DROPS = 2
"""At a degenerate vertex, the rows tried left out (:func:`_degenerate`). Measured on paper A: every answer certified
without a row was certified at the first or the second try (54 and 13 of 100 random states); in its benchmark loop
(benchmarks/tick_jobs.py) the ticks that no dropped row certifies would otherwise try all four."""
ROUNDING = np.finfo(float).eps
"""Per unit of |multiplier| |row|: the rounding a certificate's residual is charged (:func:`_rounding`). Nearly
dependent rows cancel any gradient with multipliers of 1e12, whose residual is then rounding: seen at a
least-violation vertex of paper B, where an LP found a direction of descent. Without the charge, 20 of 76
least-violation states of the example tasks were certified wrongly (the independent reference found a level 1e-3 to
0.3 above its optimum), and the two paths parted by up to 1e-2 (their nonnegative least squares find different
multipliers); with it, none, and the paths agree to 1e-13."""
PRIMAL_STEPS = 50
""":func:`from_feasible`'s iterations at most (each a change of the working set)."""
ACTIVE_TOL = 1e-9
""":func:`working_set` counts a hard row (unit length) as held at a bound when x is within this of it."""

FREE, UPPER, LOWER, FIXED = 0, 1, -1, 2


def unit_rows(A: np.ndarray, lo: np.ndarray, up: np.ndarray):
    """The hard rows and their bounds scaled to rows of unit length (a zero row is left as it is)."""
    norms = np.linalg.norm(A, axis=1)
    scale = np.where(norms > 0, 1 / np.where(norms > 0, norms, 1), 1.0)
    return A * scale[:, None], lo * scale, up * scale


def working_set(A: np.ndarray, lo: np.ndarray, up: np.ndarray, x: np.ndarray) -> np.ndarray:
    """W of a point x (unit rows): FIXED where lo = up, UPPER or LOWER within ACTIVE_TOL of that bound (the nearer
    when both are), else FREE."""
    Ax = A @ x
    s = np.zeros(len(lo), dtype=np.intc)
    near_up, near_lo = Ax >= up - ACTIVE_TOL, Ax <= lo + ACTIVE_TOL
    s[near_lo] = LOWER
    s[near_up & (~near_lo | (up - Ax <= Ax - lo))] = UPPER
    s[lo == up] = FIXED
    return s


class _IllConditioned(Exception):
    """A pivot between RANK_TOL and COND_TOL. ``rows``: the step's rows in pivot order up to the first such pivot
    (the last of them nearly depends on the others); ``of_working_set``: the step is W's."""

    def __init__(self, rows=()):
        super().__init__()
        self.rows = rows
        self.of_working_set = False


def _null_step(M: np.ndarray, Z: np.ndarray, ill_ok: bool = False):
    """(Q, R1, piv, r): the pivoted QR (M Z)' P = Q R (LAPACK's dgeqp3, Q k x k), its rank r, the first r rows of
    R (below the diagonal: reflector entries, not zeros)."""
    k, p = Z.shape[1], M.shape[0]
    if k == 0 or p == 0:
        return np.eye(k), np.zeros((0, p)), np.arange(p), 0
    qr, piv, tau, _, info = lapack.dgeqp3(np.asfortranarray((M @ Z).T))
    d = np.abs(qr.diagonal())
    r = int(np.count_nonzero(d > RANK_TOL))
    if r and d[r - 1] <= COND_TOL and not ill_ok:        # (pivoted: d decreases)
        raise _IllConditioned(piv[:int(np.argmax(d <= COND_TOL)) + 1] - 1)
    reflectors = np.zeros((k, k), order="F")
    reflectors[:, :min(k, p)] = qr[:, :min(k, p)]
    taus = np.zeros(k)
    taus[:len(tau)] = tau
    Q = lapack.dorgqr(reflectors, taus)[0]
    return Q, qr[:r], piv - 1, r


def _null_space(M, Z):
    """Z N: the null space of M within range(Z) (orthonormal columns)."""
    Q, _, _, r = _null_step(M, Z)
    return Z @ Q[:, r:]


def _least_squares_step(M, t, x, Z, steps=None, ill_ok=False):
    """x + Z y, y the least-squares step of M (x + Z y) = t within range(Z); and the null space Z N left. ``steps``
    (a list) gets the step's factors for :func:`_factors_dual`: (M, Y = Z Q1, R11, piv), and the null space left."""
    Q, R1, piv, r = _null_step(M, Z, ill_ok)
    if r:
        c = (t - M @ x)[piv]
        if r == len(c):         # R1' z = c, R1 upper triangular (dtrtrs reads only its upper triangle)
            z = lapack.dtrtrs(R1, c, lower=0, trans=1)[0]
        else:
            z = np.linalg.lstsq(np.triu(R1).T, c, rcond=None)[0]
        x = x + Z @ (Q[:, :r] @ z)
    if steps is not None:
        steps.append((M, Z @ Q[:, :r], np.triu(R1[:, :r]), piv, Z @ Q[:, r:]))
    return x, Z @ Q[:, r:]


def solve_over(H, f, A, lo, up, levels, s) -> tuple[np.ndarray, bool]:
    """(x, certified): the levels' optimum with W's rows (``s``) as equalities, and whether it is certified as the
    optimum of the whole problem (module docstring). A, lo, up: the hard rows with unit length (:func:`unit_rows`);
    levels: [(R_j, r_j)]."""
    try:
        return _solve_over(H, f, A, lo, up, levels, s)
    except _IllConditioned as ill:
        if ill.of_working_set:
            return _degenerate(H, f, A, lo, up, levels, s, ill.rows)
        return np.full(H.shape[0], np.nan), False


def _degenerate(H, f, A, lo, up, levels, s, rows) -> tuple[np.ndarray, bool]:
    """W's rows nearly dependent (``rows``: W's rows in pivot order, the last nearly a combination of the others):
    a degenerate vertex, where more rows hold x than its motion needs (paper A's tip and shaft at the same corner of
    their octagons, whose rows constrain the same motion twice). W without one of them, the last hard row first (an
    order of the rows, not of the pivoting, so that both paths drop the same row; DEGENERATE_DROPS of them at most):
    the first certified answer is taken, the dropped row holding within PRIMAL_TOL as every hard row must. Where none
    is (the optimum holds them all), W as it is, its pivots only above RANK_TOL: its rows are then consistent within
    PRIMAL_TOL or refused, and the certificate decides as everywhere."""
    held = np.flatnonzero(s != FREE)
    for i in [i for i in sorted(held[list(rows)], reverse=True) if s[i] != FIXED][:DEGENERATE_DROPS]:
        fewer = s.copy()
        fewer[i] = FREE
        try:
            x, certified = _solve_over(H, f, A, lo, up, levels, fewer)
        except _IllConditioned:
            continue
        if certified:
            return x, True
    try:
        return _solve_over(H, f, A, lo, up, levels, s, ill_ok=True)
    except _IllConditioned:            # (in a level's step)
        return np.full(H.shape[0], np.nan), False


def _solve_over(H, f, A, lo, up, levels, s, ill_ok=False):
    x, steps = _solve_on(H, f, A, lo, up, levels, s, ill_ok)
    if x is None or _violated(A, lo, up, x):
        return (np.full(H.shape[0], np.nan) if x is None else x), False
    return x, _certified(H, f, A, levels, s, x, steps)[0]


def _solve_on(H, f, A, lo, up, levels, s, ill_ok=False, levels_ill_ok=False):
    """(x, steps): the levels' optimum with W's rows as equalities, the other hard rows left out, and the solve's
    factors; (None, steps) when W's rows cannot all hold, Z'HZ is not positive definite or x is not finite.
    ``ill_ok``, ``levels_ill_ok``: W's step, the levels' steps may have pivots in (RANK_TOL, COND_TOL]."""
    n = H.shape[0]
    held = s != FREE
    C, d = A[held], np.where(s[held] == LOWER, lo[held], up[held])
    if not np.all(np.isfinite(d)):
        return None, []                                   # a row held at an infinite bound
    steps = []
    try:
        x, Z = _least_squares_step(C, d, np.zeros(n), np.eye(n), steps, ill_ok)
    except _IllConditioned as ill:
        ill.of_working_set = True
        raise
    if C.shape[0] and np.max(np.abs(C @ x - d)) > PRIMAL_TOL:
        return None, steps                                # W's rows cannot all hold
    for R, r in levels:
        x, Z = _least_squares_step(R, r, x, Z, steps, levels_ill_ok)
    if Z.shape[1]:
        factor, info = lapack.dpotrf(Z.T @ H @ Z, lower=1)
        if info:
            return None, steps                            # Z'HZ not positive definite
        x = x - Z @ lapack.dpotrs(factor, Z.T @ (H @ x + f), lower=1)[0]
    return (x if np.all(np.isfinite(x)) else None), steps


def _violated(A, lo, up, x) -> bool:
    """Some hard row misses its bounds by more than PRIMAL_TOL at x."""
    Ax = A @ x
    return bool(np.any(Ax < lo - PRIMAL_TOL) or np.any(Ax > up + PRIMAL_TOL))


def from_feasible(H, f, A, lo, up, levels, x) -> tuple[np.ndarray, bool]:
    """(x, certified): the levels' optimum reached from a point x of the hard rows by a primal active-set method
    (phase 2's (B), whose least-violation set is often a sliver where DAQP's dual iterates fail a level): W starts
    as the rows x holds, kept independent (:func:`_independent_working_set`); each iteration solves the levels over
    W (y) and, when y leaves a hard row by more than PRIMAL_TOL, steps from x toward y up to the first row that
    blocks and holds it; else moves to y, where the certificate either certifies y or names the held row with the
    most negative multiplier at the first level it refuses, which is dropped (a row that blocks at once after its
    drop is kept from then on: the multipliers missed what holds it, and dropping it again would cycle). Every
    iterate holds the hard rows (within PRIMAL_TOL) and none is worse than x at any level before the first that
    improves (each move goes toward an optimum over a set containing x). At most PRIMAL_STEPS iterations; the last
    iterate is returned, certified or not."""
    s = _independent_working_set(A, lo, up, x)
    dropped, pinned = None, set()
    for _ in range(PRIMAL_STEPS):
        y, steps = _solve_on(H, f, A, lo, up, levels, s, ill_ok=True, levels_ill_ok=True)
        if y is None:
            return x, False
        if _violated(A, lo, up, y):
            blocking = _first_blocking(A, lo, up, s, x, y)
            if blocking is None:
                return x, False
            i, side, alpha = blocking
            if i == dropped and alpha == 0:
                pinned.add(i)                             # dropped and at once blocking again: kept from now on
            x = x + alpha * (y - x)
            s[i] = side
            continue
        x = y
        try:
            certified, dropped = _certified(H, f, A, levels, s, x, steps, pinned)
        except _IllConditioned:                           # (the certificate's chain of null spaces)
            return x, False
        if certified or dropped is None:
            return x, certified
        s[dropped] = FREE
    return x, False


def _independent_working_set(A, lo, up, x) -> np.ndarray:
    """The working set of x (:func:`working_set`) with each inequality row left out that lies within COND_TOL of
    the span of the held rows before it (the fixed rows first, then those x leaves by more than PRIMAL_TOL, then
    the others, each by index): at a degenerate vertex more rows hold x than its dimensions, and a working set of
    dependent rows has no unique multipliers. (A start off a row, DAQP's answer within its tolerance, must hold that
    row: the step would not move along it.)"""
    s = working_set(A, lo, up, x)
    Ax = A @ x
    off = (Ax < lo - PRIMAL_TOL) | (Ax > up + PRIMAL_TOL)
    inequality = (s == UPPER) | (s == LOWER)
    basis = np.zeros((0, A.shape[1]))
    for i in [*np.flatnonzero(s == FIXED), *np.flatnonzero(inequality & off), *np.flatnonzero(inequality & ~off)]:
        rest = A[i] - basis.T @ (basis @ A[i])
        norm = np.linalg.norm(rest)
        if norm > COND_TOL:
            basis = np.vstack([basis, rest / norm])
        elif s[i] != FIXED:
            s[i] = FREE
    return s


def _first_blocking(A, lo, up, s, x, y):
    """(row, side, alpha): the first free hard row met on the way from x to y (the smallest alpha in [0, 1], the
    first row among equals), and the bound it meets; None when no row moves toward a bound it would leave."""
    d = y - x
    Ad, Ax = A @ d, A @ x
    moving = RANK_TOL * np.linalg.norm(d)
    best = None
    for i in np.flatnonzero(s == FREE):
        if Ad[i] > moving and np.isfinite(up[i]):
            alpha, side = (up[i] - Ax[i]) / Ad[i], UPPER
        elif Ad[i] < -moving and np.isfinite(lo[i]):
            alpha, side = (lo[i] - Ax[i]) / Ad[i], LOWER
        else:
            continue
        alpha = max(alpha, 0.0)
        if alpha < 1 and (best is None or alpha < best[2]):
            best = (i, side, alpha)
    return best


def _certified(H, f, A, levels, s, x, steps, pinned=()) -> tuple[bool, int | None]:
    """The dual half of the certificate, level by level (module docstring): by :func:`_dims_dual` or
    :func:`_factors_dual` where they apply (both sufficient), else by the nonnegative least squares over U_j.
    Also, when refused, the held inequality row to drop (:func:`_drop`), or None."""
    n = H.shape[0]
    inequality = (s == UPPER) | (s == LOWER)
    if not np.any(inequality):
        return True, None   # the chain of null spaces is the primal one: x is optimal in it by construction
    columns = (A[inequality] * s[inequality, None]).T            # s_i a_i, one column per held inequality
    fixed = A[s == FIXED]
    gradients = [(R.T @ (R @ x - r), np.linalg.norm(R) * (np.linalg.norm(R) * np.linalg.norm(x) + np.linalg.norm(r)))
                 for R, r in levels] + [(H @ x + f, np.linalg.norm(H) * np.linalg.norm(x) + np.linalg.norm(f))]
    U, chained = None, 0
    for j, (G, scale) in enumerate(gradients):
        threshold = DUAL_TOL * scale
        above = np.vstack([fixed, *(R for R, _ in levels[:j])])
        if _dims_dual(above, steps[j][4], G, threshold) or _factors_dual(steps[:j + 1], s[s != FREE], G, threshold):
            continue
        if U is None:
            U = _null_space(fixed, np.eye(n))
        for R, _ in levels[chained:j]:
            U = _null_space(R, U)
        chained = j
        if U.shape[1] == 0:
            return True, None                             # nothing below is free to move
        b = U.T @ G
        if columns.shape[1]:
            certified = _nnls_within(U.T @ columns, -b, threshold)
        else:
            certified = np.linalg.norm(b) <= threshold
        if not certified:
            return False, _drop(steps, s, gradients, j, pinned)
    return True, None


def _nnls_within(N, c, threshold) -> bool:
    """min |N lam - c| over lam >= 0, plus its rounding (:func:`_rounding`; N's columns are unit rows projected), is
    at most threshold: first the least squares over every column with its negative entries set to 0 (any lam >= 0
    bounds the minimum), then Lawson and Hanson's active-set method, which stops with the lam it has when a passive
    set's columns are (nearly) dependent. lexls.c's algorithm step for step, not scipy's nnls: where the multipliers
    are not unique, two algorithms find different ones, and the rounding charged to them decided the certificate
    differently on the two paths (polyline_guide, a least-violation state). A column enters when its w exceeds
    rounding relative to |c|: with an absolute tolerance, a state at rest on its rows (c ~ 1e-17, the rows' bounds
    +-1e-16) let no column enter, and panda7's tool held beside a port and a cone was uncertified every tick."""
    k, a = N.shape
    tol = 10 * np.finfo(float).eps * max(k, a) * np.abs(N).sum() * np.linalg.norm(c)   # w = N'(c - N lam) scales as c

    def within(lam):
        return np.linalg.norm(N @ lam - c) + ROUNDING * np.abs(lam).sum() <= threshold

    def least_squares(columns):
        if len(columns) > k:
            return None
        Q, R = np.linalg.qr(N[:, columns])
        if not np.all(np.abs(np.diag(R)) > 1e-12):
            return None
        return scipy.linalg.solve_triangular(R, Q.T @ c)

    lam = np.zeros(a)
    every = least_squares(np.arange(a))
    if every is not None and within(np.maximum(every, 0)):
        return True
    passive = np.zeros(a, dtype=bool)
    for _ in range(3 * a + 3):
        w = N.T @ (c - N @ lam)
        w[passive] = -np.inf
        t = int(np.argmax(w))
        if not w[t] > tol:
            break
        passive[t] = True
        for _ in range(3 * a + 3):      # least squares on the passive columns, kept >= 0
            columns = np.flatnonzero(passive)
            sol = least_squares(columns)
            if sol is None:
                return within(lam)
            if np.all(sol > 0):
                lam[columns] = sol
                break
            old = lam[columns]
            with np.errstate(invalid="ignore", divide="ignore"):
                steps = old / (old - sol)
            alpha = min([1.0, *steps[(sol <= 0) & ~np.isnan(steps)]])
            lam[columns] += alpha * (sol - lam[columns])
            gone = columns[lam[columns] <= tol]
            lam[gone], passive[gone] = 0.0, False
    return within(lam)


def _drop(steps, s, gradients, j, pinned=()) -> int | None:
    """The held inequality row to drop when level j is refused, or None: W's multipliers of each level i <= j by
    back-substitution through the solve's factors (:func:`_multipliers`); among the rows that no level above j holds
    back (none of its multipliers of the bound's sign beyond that level's threshold) and not ``pinned``, the one most
    negative at j."""
    held = np.flatnonzero(s != FREE)
    sides = np.where((s[held] == FIXED) | np.isin(held, list(pinned)), 0, s[held])
    locked = np.zeros(len(held), dtype=bool)
    for i, (G, scale) in enumerate(gradients[:j + 1]):
        if len(steps) <= i:
            return None
        signed = _multipliers(steps[:i + 1], G) * sides
        if i < j:
            locked |= signed > DUAL_TOL * scale
    candidates = np.flatnonzero(~locked & (sides != 0) & (signed < -DUAL_TOL * gradients[j][1]))
    return int(held[candidates[np.argmin(signed[candidates])]]) if candidates.size else None


def _multipliers(steps, G) -> np.ndarray:
    """W's multipliers sigma (in W's order, 0 on a row its step found dependent) of the gradient G, unclipped
    (:func:`_back_substitute`)."""
    return _back_substitute(steps, G)[2]


def _factors_dual(steps, held, G, threshold) -> bool:
    """Level j certified by the solve's own factors (steps: W's, then the levels above j): multipliers by
    back-substitution from the last step to W's, each R11 mu = -Y'v (v: G plus the rows' part so far; 0 on a step's
    dependent rows), W's inequality multipliers clipped to their sign (``held``: W's s), then the whole residual
    |G + sum R_l'mu_l + C_W'sigma| within threshold: the KKT conditions of level j, so sufficient. (Below a
    rank-deficient level the multipliers are not unique and this choice may miss.)"""
    v, charge, _ = _back_substitute(steps, G, held)
    return bool(np.linalg.norm(v) + charge <= threshold)


def _back_substitute(steps, G, held=None):
    """(v, charge, sigma): the multipliers of the gradient G by back-substitution from the last step to W's, each
    R11 mu = -Y'v (0 on a step's dependent rows); v = G plus the rows' part, charge their rounding
    (:func:`_rounding`), sigma W's multipliers in W's order. ``held`` (W's s): W's inequality multipliers clipped to
    their sign first (lexls.c's lex_back_substitute)."""
    v, charge = G.copy(), 0.0
    sigma = np.zeros(steps[0][0].shape[0])
    for k, (M, Y, R11, piv, _) in reversed(list(enumerate(steps))):
        if R11.shape[0] == 0:
            continue
        mu = lapack.dtrtrs(R11, -(Y.T @ v), lower=0)[0]
        if k == 0:
            if held is not None:
                sides = held[piv[:len(mu)]]
                mu = np.where((sides != FIXED) & (mu * sides < 0), 0.0, mu)
            sigma[piv[:len(mu)]] = mu
        v = v + M[piv[:len(mu)]].T @ mu
        charge += _rounding(mu, M[piv[:len(mu)]].T)
    return v, charge, sigma


def _rounding(multipliers, columns) -> float:
    """ROUNDING sum_i |multiplier_i| |column_i|, the rounding of columns @ multipliers: added to a certificate's
    residual, which certifies only when it stays within the threshold so."""
    return ROUNDING * float(np.abs(multipliers) @ np.linalg.norm(columns, axis=0))


def _dims_dual(above, Z, G, threshold) -> bool:
    """Level j certified by dimensions: the null space of the fixed rows and the levels above (``above``) contains
    the solve's null space Z after those levels, so it is Z when ``above`` has exactly n - dim Z rows, independent
    (:func:`_independent`); G's part there, Z'G, is 0 by the solve's optimality (checked), and W needs no
    multipliers."""
    n = Z.shape[0]
    if above.shape[0] != n - Z.shape[1] or not _independent(above):
        return False
    return bool(np.linalg.norm(Z.T @ G) <= threshold)


def _independent(S) -> bool:
    """The rows of S are independent, each farther than COND_TOL from the span of those before it: every pivot of
    the Cholesky of S S' above COND_TOL^2."""
    q, n = S.shape
    if q > n:
        return False
    G = S @ S.T
    Lc = np.zeros((q, q))
    for j in range(q):
        d = G[j, j] - Lc[j, :j] @ Lc[j, :j]
        if not d > COND_TOL ** 2:
            return False
        Lc[j, j] = np.sqrt(d)
        Lc[j + 1:, j] = (G[j + 1:, j] - Lc[j + 1:, :j] @ Lc[j, :j]) / Lc[j, j]
    return True


def split(H, f, A, lower, upper, break_points):
    """(H, f, unit hard rows, their bounds, levels) of DAQP's hierarchical problem: x's n simple bounds (infinite
    here: the box is among the rows), then the rows A with bounds lower/upper[n:], split at the break points (the
    first ends the hard rows; level j's rows have lower = upper = r_j). A level's zero rows with a zero target
    (terms of weight 0: a procedure's idle phases') are left out, and the levels left empty: they add 0 to every
    sum and factor, and leave no minimizer (:func:`level_rows`)."""
    n = H.shape[0]
    A = A.reshape(-1, n)
    ends = [b - n for b in break_points]
    A_hard, lo, up = unit_rows(A[:ends[0]], lower[n:n + ends[0]], upper[n:n + ends[0]])
    levels = [level_rows(A[a:b], lower[n + a:n + b]) for a, b in zip(ends[:-1], ends[1:])]
    return H, f, A_hard, lo, up, [(R, r) for R, r in levels if r.size]


def level_rows(R: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A level's rows R and targets r without the rows that are zero with a zero target."""
    kept = np.any(R != 0, axis=1) | (r != 0)
    return R[kept], r[kept]


def polish(H, f, A, lower, upper, break_points, x) -> tuple[np.ndarray, bool]:
    """(x*, certified): the levels solved exactly over the working set of x (an answer of DAQP's hierarchical
    mode), in DAQP's data layout (:func:`split`); where that is not certified, from x by :func:`from_feasible`
    (paper A's degenerate vertices, where DAQP's working set holds the rows nearly dependent on each other: in its
    pushed closed loop, 206 of 500 ticks, all then certified). Uncertified: x's own exact solve."""
    H, f, A_hard, lo, up, levels = split(H, f, A, lower, upper, break_points)
    x_exact, certified = solve_over(H, f, A_hard, lo, up, levels, working_set(A_hard, lo, up, x))
    if certified:
        return x_exact, True
    x_from, certified = from_feasible(H, f, A_hard, lo, up, levels, np.array(x, dtype=float))
    return (x_from, True) if certified else (x_exact, False)
