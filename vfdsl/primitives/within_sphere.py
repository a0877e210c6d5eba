"""Stay inside a ball, exactly (lecture, slide 44, linearized at the closest point of the sphere).

Keep the frame origin p within r of a center c:  || p + dx_p - c || <= r. Every tick the ball is replaced
by its tangent plane at the sphere point closest to p, with outward normal n = (p - c) / || p - c ||:

    n . (p - c + dx_p) <= r    ->    -n J_v dq >= -r + n . (p - c)

One row, no polytope: at rest (dx_p = 0) it reads || p - c || <= r, the true distance. From any p in the
ball, a step dx_p that keeps the row leaves it by at most sqrt(r^2 + s^2) - r <= s^2 / (2 r),
s = || dx_p ||; the next tick's plane pulls it back. When no coordinate of p - c exceeds COINCIDENT,
n is the tool axis (any unit vector keeps that bound; the row is then far from binding).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import normalize
from vfdsl.compiler.rows import Rows, lower_bounds
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import SIZE, ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

COINCIDENT = 1e-12     # m: when no coordinate of p - c is larger, the direction p - c is not used

BALL = (ArgSpec("center", "point", "the ball's center c"),
        ArgSpec("radius", "length", "the ball's radius r", range=SIZE))

SPEC = ConstraintSpec(
    name="within_sphere",
    summary="keep the frame origin inside a ball, exactly (its tangent plane at the closest point every tick)",
    subject=True,
    args=BALL,
    source="Taylor, lecture notes, slide 44 (the ball linearized at its closest point)",
    metric="length", row_unit="m", stated_by=("length", "radius"), exact_rows="exact (tangent plane)",
    reference_point="center", error_is_distance=True,
)


def tangent_plane(c, ctx):
    """(n J_v, n . (p - c), r) of a ball constraint: n = (p - c) / || p - c || (the tool axis at the
    center) on the step, the frame origin's height along n, the radius. p - c is first divided by its
    largest coordinate, so that no distance over- or underflows."""
    f = ctx.frame(c.frame)
    v = f.p - ctx.point(c.args["center"])
    largest = ca.mmax(ca.fabs(v))
    n = ca.if_else(largest > COINCIDENT, normalize(v / ca.fmax(largest, COINCIDENT)), f.axis)
    return n.T @ f.Jv, n.T @ v, ctx.scalar(c.args["radius"])


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    a, height, r = tangent_plane(c, ctx)
    return lower_bounds(-a, height - r, ["tangent plane"])
