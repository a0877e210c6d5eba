"""Tolerances: positive, of a plausible size, realizable by the joints, and restorable within a tick.

- **Sign and size.** The front end checks a tolerance's dimension (length or angle) and sign in the file;
  here a tolerance built in Python is checked again, and a size outside [0.1 um, 20 mm] (lengths) or
  [1 urad, 20 deg] (angles) is flagged as a likely unit slip.
- **Joint resolution.** With joint steps of res_k (the robot's sidecar), the frame can be placed along a
  facet row a (a = -u J, one row of the constraint at the start) only to within half a step of each
  joint: q_res = 1/2 max_rows sum_k |a_k| res_k. A tolerance below q_res cannot be realized.
- **Restore time.** The joint speeds and the frames' speed limits bound one tick's motion; the reach
  along a facet row is s_i = max a_i dq over those rate rows (an LP). Undoing a deviation of one
  tolerance takes ceil(eps / min_i s_i) ticks: a note from 2 ticks, a warning above SLOW_RESTORE_TICKS.
"""

from __future__ import annotations

import math

import numpy as np

from vfdsl.check.linearized import ConstraintRows, subject
from vfdsl.check.lp import LinearSystem
from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS

PLAUSIBLE = {"length": (1e-7, 0.02), "angle": (1e-6, math.radians(20))}
SLOW_RESTORE_TICKS = 10      # a restore slower than this many ticks is a warning; 2..10 ticks a note


def analyse_values(task: ir.Task) -> list[Finding]:
    """Sign and size of every tolerance (needs no robot state)."""
    findings = []
    for c in task.constraints:
        if c.tolerance is None:
            continue
        kind = CONSTRAINTS[c.primitive].tolerance
        eps = c.tolerance
        heading = subject(c)
        if not math.isfinite(eps) or eps <= 0:
            findings.append(Finding("tolerance-nonpositive", Severity.ERROR,
                                    f"the tolerance is {eps!r}: it must be a positive, finite {kind}", c.span,
                                    "write `within <a positive value>`", heading, {"tolerance": eps}))
            continue
        low, high = PLAUSIBLE[kind]
        if not low <= eps <= high:
            side = "below" if eps < low else "above"
            findings.append(Finding(
                "tolerance-implausible", Severity.WARNING,
                f"a tolerance of {quantity(eps, kind)} is {side} the plausible range "
                f"[{quantity(low, kind)}, {quantity(high, kind)}] for a {kind}: a unit slip?", c.span,
                "give the unit explicitly, e.g. `within 0.5 mm` or `within 1 deg`", heading,
                {"tolerance": eps, "range": [low, high]}))
    return findings


def realizable(rows: ConstraintRows, resolution: np.ndarray) -> float:
    """Half a step of every joint, summed along the worst facet row: how finely the joints place the frame."""
    return float(0.5 * np.max(np.abs(rows.A) @ resolution))


def one_tick_reach(rows: ConstraintRows, rates: LinearSystem) -> float:
    """The smallest, over the facet rows, of how far one tick can move along that row at the rate limits."""
    return min(rates.reach(a) for a in rows.A)


def analyse_at_start(rows: list[ConstraintRows], resolution: np.ndarray | None, nq: int, period: float
                     ) -> list[Finding]:
    findings = []
    rate_rows = [r for r in rows if CONSTRAINTS[r.constraint.primitive].rate and not r.constraint.soft]
    rates = LinearSystem.from_rows(rate_rows, nq) if rate_rows else None
    for r in rows:
        c = r.constraint
        if c.tolerance is None or not c.tolerance > 0 or not len(r.A):
            continue
        kind = CONSTRAINTS[c.primitive].tolerance
        eps = c.tolerance
        heading = subject(c)
        if resolution is not None:
            finest = realizable(r, resolution)
            if eps < finest:
                findings.append(Finding(
                    "tolerance-below-resolution", Severity.WARNING,
                    f"the tolerance {quantity(eps, kind)} is finer than the {quantity(finest, kind)} to which "
                    f"the joints' resolution can place the frame along this constraint at the start "
                    f"(half a step of each joint, summed)", c.span,
                    f"a tolerance of at least {quantity(finest, kind)} is realizable on this robot",
                    heading, {"tolerance": eps, "realizable": finest}))
        if rates is not None:
            reach = one_tick_reach(r, rates)
            if 0 < reach < eps:
                ticks = math.ceil(eps / reach)
                findings.append(Finding(
                    "tolerance-restore-ticks", Severity.WARNING if ticks > SLOW_RESTORE_TICKS else Severity.NOTE,
                    f"at the speed limits one tick ({quantity(period, 'time')}) moves only {quantity(reach, kind)} "
                    f"along this constraint's worst facet: undoing a deviation of one tolerance "
                    f"({quantity(eps, kind)}) takes {ticks} ticks ({ticks * period:.3g} s)", c.span,
                    "raise the joint_speed fraction or the speed limits, or shorten the period", heading,
                    {"tolerance": eps, "reach_per_tick": reach, "ticks": ticks, "period": period}))
    return findings
