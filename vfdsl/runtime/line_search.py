"""Phase 2's backtracking: a least-violation step goes only as far as it truly brings the fixtures back.

Phase 2 (:mod:`vfdsl.runtime.qp`) brings the fixtures back as far as their rows, linearized at q, predict. Far off
a fixture, with the arm stretched at its reach, that prediction can be wrong by more than it promises: panda7 held
within a sphere 1 m away came to 131 mm, then every tick's rows predicted 11 mm of progress for a step at the speed
limit whose second-order remainder took it all back, and the arm alternated between 131.20 and 130.54 mm, every
joint reversing at full speed each tick, for as long as the task ran.

So the step is judged by the fixtures' own rows re-evaluated where it ends. The measure of a state q' is phase 2's,
with this tick's weights w_g:

    phi(q') = sum_g rho t_g / w_g + t_g^2 / 2,    t_g the largest violation of group g's hard rows at q' at rest

over the groups off at rest at q (a row at rest: max(lba_i(q'), -uba_i(q')), the rows' bounds being their tolerance
less their error at q'; soft rows are left out, their slack takes their excess; a violation within feas_tol counts
as none, as phase 1 accepts; inf where a bound is not a number). A group that holds at q is left out: a step's
second-order remainder takes it out as phase 1's do, and counted (at the weight of the floor, 1e4 per m) a fixture
held at its boundary stopped every step for good (a port at 0.5 mm while a cone 42 deg off came back); once out, it
is off at rest at the next tick, counted, and brought back first (docs/runtime.md, Phase 2). Along phase 2's step x,
the tick takes a x for the largest a in 1, 1/2, ..., 2^-(LINE_SEARCH_TRIALS - 1) with

    phi(q + a dq) < phi(q) + c a min(s, 0),     s = (phi(q + h dq) - phi(q)) / h

(h = SLOPE_STEP, c = SUFFICIENT_DECREASE: Armijo's rule, with the true measure's slope along the step, not the
rows': the paper's rotation rows are first-order exact only near their fixture, and at 90 deg off a direction its
sine is flat where the angle falls at full speed), and holds still (a = 0) if none passes, the fixtures' violations
named. Each step taken lowers phi, by at least c a |s|, so least-violation ticks cannot alternate between two
states. a x lies in the box B. The trials are a chain of switches: a trial's rows are evaluated only when the one
before failed, so a least-violation tick whose step holds evaluates them twice (the slope, a = 1).

The rows judge a step only where they agree with the truth at its start: where the true measure falls less than
FIRST_ORDER_AGREEMENT times as fast as the linearized rows say (s > r m, m the rows' own slope along x, the same
quotient), the step is taken whole, as before the search. The paper's rotation rows are exact to first order only
near their fixture, and a cone's polygon turns with the tool: 64 deg off a cone beside a port, the rows' measure rose
along a step that turned the tool 0.04 deg nearer, and with the search everywhere the tool stopped there for good
(with r = 0.5, it crawled: 60 deg after 400 ticks, where the step whole reached the cone in 299). Where the rows are
the fixture's derivative (a sphere, a plane, a point: a chatter's states) the two slopes agree to rounding.

The search is left out where nothing is to be brought back (phi(q) = 0: a phase 1 that failed numerically; the step
is then held like phase 1's, to its rows) and where the box itself forces a motion (q outside its joint limits: the
rest motion x_0 != 0), a return that is the joints', not the fixtures'.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

LINE_SEARCH_TRIALS = 6
"""The step lengths tried: 1, 1/2, ..., 1/32 of phase 2's step."""
SUFFICIENT_DECREASE = 0.1
"""c: a step is taken when the fixtures truly come back by at least this fraction of what the measure's slope along
it promises."""
SLOPE_STEP = 1e-4
"""h: the slope of the measure along phase 2's step is its difference quotient over this fraction of the step."""
FIRST_ORDER_AGREEMENT = 0.9
"""The rows are trusted to judge a step by when the true measure starts falling along it at least this fraction as
fast as their linearization says (s <= r m); else the step is taken whole."""


def group_worst(E: ca.DM, violation):
    """t_g: the largest entry of ``violation`` over group g's rows (E's column g)."""
    columns = np.array(E).T
    return ca.vertcat(*(ca.mmax(violation[np.flatnonzero(column).tolist()]) for column in columns))


def measure(E: ca.DM, violation, counted, w, tol: float, rho: float):
    """phi: phase 2's measure sum_g rho t_g / w_g + t_g^2 / 2 of the rows' ``violation``, t_g the largest over group
    g's rows ``counted`` (1 per row counted, else 0), a violation within ``tol`` counting as none."""
    t = group_worst(E, counted * violation)
    t = ca.if_else(t > tol, t, 0)
    return ca.sum1(rho * t / w + t * t / 2)


def line_search(qp_data: ca.Function, inputs: list[ca.MX], E: ca.DM, tol: float, rho: float,
                name: str) -> ca.Function:
    """``name(data..., x, w, counted, phi0, m) -> a``: the length of phase 2's step x from the state ``data``'s q
    (``inputs``: the step's data arguments, q first) by this module's rule, phi0 = phi(q), w the groups' weights,
    ``counted`` 1 per row the measure counts (a hard row of a group off at rest), else 0, m the slope the linearized
    rows give the measure along x."""
    nq = inputs[0].size1()
    phi_at = _measure_function(qp_data, E, tol, rho, f"{name}_measure")
    data = [ca.MX.sym(f"{name}_{k}", v.sparsity()) for k, v in enumerate(inputs)]
    n, m, G = qp_data.size1_out(0), qp_data.size1_out(2), E.size2()
    x, w, counted, phi0, slope = ca.MX.sym("x", n), ca.MX.sym("w", G), ca.MX.sym("counted", m), \
        ca.MX.sym("phi0"), ca.MX.sym("slope")
    args = [*data, x, w, counted, phi0, slope]      # the chain's: slope is the true measure's

    def phi(a: float) -> ca.MX:
        return phi_at(data[0] + a * x[:nq], *data[1:], w, counted)

    chain = ca.Function(f"{name}_none", args, [ca.MX(0)])
    for k in reversed(range(LINE_SEARCH_TRIALS)):
        a = 0.5 ** k
        passes = phi(a) < phi0 + SUFFICIENT_DECREASE * a * ca.fmin(slope, 0)
        chain = ca.Function(f"{name}_try{k}", args, [ca.Function.if_else(
            f"{name}_pick{k}", ca.Function(f"{name}_take{k}", args, [ca.MX(a)]), chain)(passes, *args)])
    predicted = ca.MX.sym("predicted")
    true_slope = (phi(SLOPE_STEP) - phi0) / SLOPE_STEP
    whole = ca.Function(f"{name}_whole", args, [ca.MX(1)])
    misled = true_slope > FIRST_ORDER_AGREEMENT * predicted
    length = ca.Function.if_else(f"{name}_if_trusted", whole, chain)(misled, *args[:-1], true_slope)
    return ca.Function(name, [*args[:-1], predicted], [length])


def _measure_function(qp_data: ca.Function, E: ca.DM, tol: float, rho: float, name: str) -> ca.Function:
    """``name(data..., w, counted) -> phi``: the measure at the state ``data``'s q, from ``qp_data``'s rows' bounds
    there (an SX qp_data's Jacobians pruned: scalar code); inf where a row's bound is not a number (the fixture's
    geometry undefined there: never a step's end)."""
    sx = qp_data.is_a("SXFunction")
    symbols = qp_data.sx_in() if sx else qp_data.mx_in()
    lba, uba = qp_data.call(symbols)[3:5]
    Sym = ca.SX if sx else ca.MX
    w, counted = Sym.sym("w", E.size2()), Sym.sym("counted", E.size1())
    phi = measure(E, ca.fmax(ca.fmax(lba, -uba), 0), counted, w, tol, rho)
    defined = ca.logic_and(ca.mmin(lba <= ca.inf), ca.mmin(uba >= -ca.inf))
    return ca.Function(name, [*symbols, w, counted], [ca.if_else(defined, phi, ca.inf)])
