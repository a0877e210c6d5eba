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
  min_{lambda >= 0} |U_j'(G_j + C_in' S lambda)| is zero (within ``DUAL_TOL`` |G_j|).

The certificate is the KKT conditions of level j over the hard rows and the optimal sets of the levels above
(the minimizers of |R_i x - r_i|^2 over a convex set share R_i x, so that set is the hard rows and R_i x = R_i x*
for i < j): sufficient, the problems being convex. So a certified x is x*, whatever W it came from; W decides only
whether a certificate is found (it is when W holds the rows active at x* with a positive multiplier at some level
and no other row that the levels would leave). The generated C (``vfdsl/codegen/lexls.c``) runs the same steps
with its own Householder QR, Cholesky and Lawson-Hanson NNLS; this module, the interpreted path's, uses LAPACK's
(through scipy) and scipy's NNLS. No library offers the lexicographic solve over a working set with this
certificate (DAQP's hierarchical mode, which both paths call when no certificate is found, holds each level to its
tolerance, not exactly); the C is ours because the generated tick links no LAPACK.

Two cheaper sufficient tests run first at each level (:func:`_factors_dual`: multipliers from the solve's own
factors; :func:`_dims_dual`: when the fixed rows and the levels above cut as many dimensions as the solve's steps
up to that level did, U_j is the solve's null space, where G_j is zero by construction); the nonnegative least
squares, and the chain of U_j it needs, only where neither certifies the level.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize
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
    n = H.shape[0]
    held = s != FREE
    C, d = A[held], np.where(s[held] == LOWER, lo[held], up[held])
    if not np.all(np.isfinite(d)):
        return np.full(n, np.nan), False                  # a row held at an infinite bound
    steps = []
    try:
        x, Z = _least_squares_step(C, d, np.zeros(n), np.eye(n), steps, ill_ok)
    except _IllConditioned as ill:
        ill.of_working_set = True
        raise
    if C.shape[0] and np.max(np.abs(C @ x - d)) > PRIMAL_TOL:
        return x, False                                   # W's rows cannot all hold
    for R, r in levels:
        x, Z = _least_squares_step(R, r, x, Z, steps)
    if Z.shape[1]:
        factor, info = lapack.dpotrf(Z.T @ H @ Z, lower=1)
        if info:
            return x, False                               # Z'HZ not positive definite
        x = x - Z @ lapack.dpotrs(factor, Z.T @ (H @ x + f), lower=1)[0]
    if not np.all(np.isfinite(x)):
        return x, False
    Ax = A @ x
    if np.any(Ax < lo - PRIMAL_TOL) or np.any(Ax > up + PRIMAL_TOL):
        return x, False
    return x, _certified(H, f, A, levels, s, x, steps)


def _certified(H, f, A, levels, s, x, steps) -> bool:
    """The dual half of the certificate, level by level (module docstring): by :func:`_dims_dual` or
    :func:`_factors_dual` where they apply (both sufficient), else by the nonnegative least squares over U_j."""
    n = H.shape[0]
    inequality = (s == UPPER) | (s == LOWER)
    if not np.any(inequality):
        return True         # the chain of null spaces is the primal one: x is optimal in it by construction
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
            return True                                   # nothing below is free to move
        b = U.T @ G
        if columns.shape[1]:
            residual = scipy.optimize.nnls(U.T @ columns, -b)[1]
        else:
            residual = np.linalg.norm(b)
        if residual > threshold:
            return False
    return True


def _factors_dual(steps, held, G, threshold) -> bool:
    """Level j certified by the solve's own factors (steps: W's, then the levels above j): multipliers by
    back-substitution from the last step to W's, each R11 mu = -Y'v (v: G plus the rows' part so far; 0 on a step's
    dependent rows), W's inequality multipliers clipped to their sign (``held``: W's s), then the whole residual
    |G + sum R_l'mu_l + C_W'sigma| within threshold: the KKT conditions of level j, so sufficient. (Below a
    rank-deficient level the multipliers are not unique and this choice may miss.)"""
    v = G.copy()
    for k, (M, Y, R11, piv, _) in reversed(list(enumerate(steps))):
        if R11.shape[0] == 0:
            continue
        mu = lapack.dtrtrs(R11, -(Y.T @ v), lower=0)[0]
        if k == 0:
            sides = held[piv[:len(mu)]]
            mu = np.where((sides != FIXED) & (mu * sides < 0), 0.0, mu)
        v = v + M[piv[:len(mu)]].T @ mu
    return bool(np.linalg.norm(v) <= threshold)


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
    mode), in DAQP's data layout (:func:`split`)."""
    H, f, A_hard, lo, up, levels = split(H, f, A, lower, upper, break_points)
    return solve_over(H, f, A_hard, lo, up, levels, working_set(A_hard, lo, up, x))
