"""The polytope behind a round tolerance: how far the rows of a constraint really let the error go.

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

from vfdsl.compiler.geometry import polygon_angles, sphere_directions


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
