"""Stay within a distance of a point (lecture, "keep tool tip near a point", slide 44).

|| p + dx_p - P || <= r, approximated by the n x m sphere polytope (as stays_at with eps = r).
"""

import casadi as ca

from vfdsl.compiler.geometry import sphere_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="within_distance",
    summary="keep the frame origin at most `distance` from a point",
    subject=True,
    args=(ArgSpec("center", "point", "the goal point"),
          ArgSpec("distance", "length", "the largest allowed distance", range=POSITIVE)),
    resolution="sphere",
    source="Taylor, lecture notes, slide 44",
)


def lower(c, ctx) -> Rows:
    f = ctx.frame(c.frame)
    delta = f.p - ctx.point(c.args["center"])
    return facets(ca.DM(sphere_directions(*c.resolution)), delta, ctx.scalar(c.args["distance"]), f.Jv)
