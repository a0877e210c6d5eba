"""Polytope resolution: how far the rows of a constraint really let the error go.

A ball || v || <= eps is replaced by facets u_i . v <= eps (DESIGN errata 3-5). With U the unit facet
directions (rows), the polytope P = {v : U v <= eps} is

- bounded iff the directions positively span the space, i.e. the origin lies strictly inside their
  convex hull (a 2-gon, or an n x m parametrization whose directions all lie in one plane, is not);
- larger than the ball: its farthest vertex, the circumradius rho eps, is the largest error the rows
  admit -- the guaranteed bound. rho = 1 / cos(pi / n) for the regular n-gon, sqrt 3 for the cube that
  the paper's 4 x 4 sphere parametrization reduces to.

The vertices come from Qhull's half-space intersection (scipy). ``overshoot`` is rho - 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

from vfdsl.check.linearized import describe, subject, value_of, where
from vfdsl.check.report import Bound, Finding, Severity, quantity
from vfdsl.compiler.geometry import polygon_angles, sphere_directions
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS

SEARCH_LIMIT = 24              # largest n (and m) tried for the smallest resolution under an overshoot


@dataclass(frozen=True)
class PolytopeGeometry:
    """The polytope of one resolution, in units of eps."""

    shape: str                 # "sphere" or "polygon"
    resolution: tuple[int, ...]
    listed: int                # directions the parametrization lists (n m, or n)
    unique: int                # facets after removing repeated directions
    bounded: bool
    circumradius: float        # rho: the farthest vertex is rho eps away (inf when unbounded)

    @property
    def overshoot(self) -> float:
        return self.circumradius - 1.0

    @property
    def label(self) -> str:
        return "x".join(map(str, self.resolution))


def directions(shape: str, resolution: tuple[int, ...]) -> np.ndarray:
    """Unit facet directions: rows in 3-D for the sphere polytope, in the polygon's own plane for a polygon."""
    if shape == "sphere":
        return sphere_directions(*resolution)
    angles = polygon_angles(resolution[0])          # n distinct angles: no repeated directions
    return np.column_stack([np.cos(angles), np.sin(angles)])


def positively_spanning(U: np.ndarray) -> bool:
    """True when {v : U v <= 1} is bounded: the origin is strictly inside the convex hull of the rows of U."""
    d = U.shape[1]
    if len(U) <= d or np.linalg.matrix_rank(U) < d:
        return False
    try:
        hull = ConvexHull(U)
    except QhullError:
        return False
    return bool(np.all(hull.equations[:, -1] < -1e-12))


def circumradius(U: np.ndarray) -> float:
    """max || v || over {v : U v <= 1} (inf when unbounded), from the polytope's vertices."""
    if not positively_spanning(U):
        return math.inf
    halfspaces = np.column_stack([U, -np.ones(len(U))])
    vertices = HalfspaceIntersection(halfspaces, np.zeros(U.shape[1])).intersections
    return float(np.linalg.norm(vertices, axis=1).max())


@lru_cache(maxsize=None)
def geometry(shape: str, resolution: tuple[int, ...]) -> PolytopeGeometry:
    U = directions(shape, resolution)
    return PolytopeGeometry(shape, resolution, math.prod(resolution), len(U), positively_spanning(U),
                            circumradius(U))


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


def constraint_geometry(c: ir.Constraint) -> PolytopeGeometry | None:
    """The polytope behind a constraint's rows, or None when its rows are exact (planes, joint bounds)."""
    shape = CONSTRAINTS[c.primitive].resolution_shape(c.args)
    if shape is None or c.resolution is None:
        return None
    return geometry(shape, tuple(c.resolution))


def stated_size(c: ir.Constraint, task: ir.Task) -> tuple[str, float] | None:
    """(kind, SI value) of what the constraint bounds: its tolerance, or its distance or speed argument."""
    spec = CONSTRAINTS[c.primitive]
    if spec.stated_by is not None:
        kind, name = spec.stated_by
        return kind, float(value_of(c.args[name], task).value)
    if c.tolerance is None:
        return None
    return spec.tolerance, float(c.tolerance)


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
            table.append(Bound(describe(c), where(c), kind, size, g.label, g.unique, g.circumradius * size))
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
        data = {"resolution": list(g.resolution), "listed": g.listed, "facets": g.unique,
                "circumradius_factor": g.circumradius, "stated": size, "worst": g.circumradius * size}
        if not g.bounded:
            findings.append(Finding(
                "polytope-unbounded", Severity.ERROR,
                f"the {g.label} {shape_words} ({g.unique} unique facet{'s' * (g.unique != 1)}) does not enclose "
                f"the origin: its rows leave the error unbounded in some direction", c.span,
                _suggest(g.shape, overshoot), heading, data))
            continue
        if g.overshoot > overshoot + 1e-12:
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
