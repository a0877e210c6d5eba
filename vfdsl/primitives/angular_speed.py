"""Angular speed limit of a frame:  || dx_r || <= w_max dt, by the n x m sphere polytope."""

import casadi as ca

from vfdsl.compiler.geometry import sphere_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="angular_speed",
    summary="bound the angular speed of the frame",
    subject=True,
    args=(ArgSpec("max", "angular_speed", "the largest angular speed"),),
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-C",
)


def lower(c, ctx) -> Rows:
    f = ctx.frame(c.frame)
    return facets(ca.DM(sphere_directions(*c.resolution)), ca.DM.zeros(3), ctx.scalar(c.args["max"]) * ctx.dt, f.Jw)
