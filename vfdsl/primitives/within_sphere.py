"""Stay inside a ball, exactly (lecture, slide 44, linearized at the closest point of the sphere).

Keep the frame origin p within r of a center c:  || p + dx_p - c || <= r. Every tick the ball is replaced
by its tangent plane at the sphere point closest to p, with outward normal n = (p - c) / || p - c ||:

    n . (p - c + dx_p) <= r    ->    -n J_v dq >= -r + n . (p - c)

One row, no polytope: at rest (dx_p = 0) it reads || p - c || <= r, the true distance. From any p in the
ball, a step dx_p that keeps the row leaves it by at most sqrt(r^2 + s^2) - r <= s^2 / (2 r),
s = || dx_p ||; the next tick's plane pulls it back. When no coordinate of p - c exceeds COINCIDENT,
n is the tool axis (any unit vector keeps that bound; the row is then far from binding).
"""

import casadi as ca

from vfdsl.compiler.geometry import normalize
from vfdsl.compiler.rows import Rows, lower_bounds
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ConstraintSpec

COINCIDENT = 1e-12     # m: when no coordinate of p - c is larger, the direction p - c is not used

SPEC = ConstraintSpec(
    name="within_sphere",
    summary="keep the frame origin inside a ball, exactly (its tangent plane at the closest point every tick)",
    subject=True,
    args=(ArgSpec("center", "point", "the ball's center c"),
          ArgSpec("radius", "length", "the ball's radius r", range=POSITIVE)),
    source="Taylor, lecture notes, slide 44 (the ball linearized at its closest point)",
)


def radial(f, center):
    """The unit normal n = (p - c) / || p - c || of the sphere through p, or the tool axis at the center.
    p - c is first divided by its largest coordinate, so that no distance over- or underflows."""
    v = f.p - center
    largest = ca.mmax(ca.fabs(v))
    return ca.if_else(largest > COINCIDENT, normalize(v / ca.fmax(largest, COINCIDENT)), f.axis)


def lower(c, ctx) -> Rows:
    f = ctx.frame(c.frame)
    center = ctx.point(c.args["center"])
    n = radial(f, center)
    return lower_bounds(-n.T @ f.Jv, n.T @ (f.p - center) - ctx.scalar(c.args["radius"]), ["tangent plane"])
