"""Polytope resolution findings: whether a constraint's polytope (:mod:`vfdsl.compiler.polytope`) is bounded,
how far over its stated size it lets the error go, and the smallest resolution that keeps an overshoot.
"""

from __future__ import annotations

from functools import lru_cache

from vfdsl.check.report import Bound, Finding, Severity, quantity
from vfdsl.compiler.geometry import sphere_directions
from vfdsl.compiler.polytope import PolytopeGeometry, geometry
from vfdsl.primitives.bounds import admitted, constraint_geometry, guaranteeing, stated_size
from vfdsl.ir import model as ir
from vfdsl.ir.constraints import describe, subject, where
from vfdsl.primitives import CONSTRAINTS

SEARCH_LIMIT = 24              # largest n (and m) tried for the smallest resolution under an overshoot


@lru_cache(maxsize=None)
def smallest_resolution(shape: str, overshoot: float) -> PolytopeGeometry | None:
    """The resolution with the fewest facets (then the fewest listed directions) whose overshoot is at most
    ``overshoot``; None if none up to SEARCH_LIMIT."""
    if shape == "polygon":
        # rho = 1 / cos(pi / n) decreases with n
        for n in range(3, SEARCH_LIMIT + 1):
            g = geometry("polygon", (n,))
            if g.overshoot <= overshoot:
                return g
        return None
    candidates = sorted(((len(sphere_directions(n, m)), n * m, (n, m))
                         for n in range(3, SEARCH_LIMIT + 1) for m in range(3, SEARCH_LIMIT + 1)))
    for _, _, resolution in candidates:
        g = geometry("sphere", resolution)
        if g.overshoot <= overshoot:
            return g
    return None


def bounds_table(task: ir.Task) -> list[Bound]:
    """One row per constraint that bounds an error: stated size, resolution and the worst admitted error."""
    table = []
    for c in task.constraints:
        stated = stated_size(c, task)
        if stated is None:
            continue
        kind, size = stated
        g = constraint_geometry(c)
        if g is None:
            table.append(Bound(describe(c), where(c), kind, size, CONSTRAINTS[c.primitive].exact_rows, None, size))
        else:
            table.append(Bound(describe(c), where(c), kind, size, g.label, g.unique,
                               admitted(c, task, g.circumradius * size)))
    return table


def analyse(task: ir.Task, overshoot: float) -> list[Finding]:
    """Boundedness, circumradius against the stated size, and repeated directions, per constraint."""
    findings = []
    for c in task.constraints:
        g = constraint_geometry(c)
        stated = stated_size(c, task)
        if g is None or stated is None:
            continue
        kind, size = stated
        heading = subject(c)
        shape_words = "sphere polytope" if g.shape == "sphere" else "polygon"
        worst = admitted(c, task, g.circumradius * size)
        data = {"resolution": list(g.resolution), "listed": g.listed, "facets": g.unique,
                "circumradius_factor": g.circumradius, "stated": size, "worst": worst}
        if not g.bounded:
            findings.append(Finding(
                "polytope-unbounded", Severity.ERROR,
                f"the {g.label} {shape_words} ({g.unique} unique facet{'s' * (g.unique != 1)}) does not enclose "
                f"the origin: its rows leave the error unbounded in some direction", c.span,
                _suggest(g.shape, overshoot), heading, data))
            continue
        if worst > (1 + overshoot) * size * (1 + 1e-9) and worst > g.circumradius * size * (1 + 1e-9):
            fit = guaranteeing(c, task, g.circumradius, size)
            findings.append(Finding(
                "polytope-overshoot", Severity.WARNING,
                f"the {g.label} {shape_words} bounds a sine of the angle, not the angle (docs/primitives.md, note 8): "
                f"at this half-angle its rows admit errors up to {quantity(worst, kind)}, {worst / size - 1:.0%} over "
                f"the stated {quantity(size, kind)} (limit {overshoot:.0%})", c.span,
                f"state {quantity(fit, kind)} to guarantee {quantity(size, kind)} (a finer resolution cannot: the "
                f"sine's slope at the half-angle is the cause)", heading, data))
        elif g.overshoot > overshoot + 1e-12:
            findings.append(Finding(
                "polytope-overshoot", Severity.WARNING,
                f"the {g.label} {shape_words} ({g.unique} facets) admits errors up to "
                f"{quantity(g.circumradius * size, kind)}, {g.overshoot:.0%} over the stated {quantity(size, kind)} "
                f"(limit {overshoot:.0%}; its farthest vertex is {g.circumradius:.3f} x the facet distance)",
                c.span, _suggest(g.shape, overshoot, g, size, kind), heading, data))
        if g.unique < g.listed:
            findings.append(Finding(
                "polytope-repeated-directions", Severity.NOTE,
                f"the {g.label} parametrization lists {g.listed} directions, {g.unique} of them unique "
                f"({g.listed - g.unique} repeated, removed)", c.span, None, heading, data))
    return findings


def _suggest(shape: str, overshoot: float, current: PolytopeGeometry | None = None, size: float = 0.0,
             kind: str = "length") -> str:
    best = smallest_resolution(shape, overshoot)
    if best is None:
        text = f"no resolution up to {SEARCH_LIMIT} keeps the overshoot under {overshoot:.0%}"
    else:
        text = (f"resolution {best.label} ({best.unique} facets) keeps the overshoot at {best.overshoot:.1%} "
                f"(<= {overshoot:.0%})")
    if current is not None and current.bounded:
        text += (f"; or keep {current.label} and state {quantity(size / current.circumradius, kind)} to "
                 f"guarantee {quantity(size, kind)}")
    return text
