"""Cartesian speed limit of a frame origin:  || dx_p || <= v_max dt, by the n x m sphere polytope."""

import casadi as ca

from vfdsl.compiler.geometry import sphere_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="speed",
    summary="bound the linear speed of the frame origin",
    subject=True,
    args=(ArgSpec("max", "speed", "the largest speed", range=POSITIVE),),
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-C",
    rate=True,
)


def lower(c, ctx) -> Rows:
    return speed_rows(c, ctx, ctx.frame(c.frame).Jv)


def speed_rows(c, ctx, J) -> Rows:
    """Sphere-polytope rows || J dq || <= max dt (J: the linear or the angular block of the frame Jacobian)."""
    return facets(ca.DM(sphere_directions(*c.resolution)), ca.DM.zeros(3), ctx.scalar(c.args["max"]) * ctx.dt, J)
