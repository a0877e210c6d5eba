"""Angular speed limit of a frame:  || dx_r || <= w_max dt, by the n x m sphere polytope."""

from vfdsl.compiler.rows import Rows
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ConstraintSpec
from vfdsl.primitives.speed import speed_rows

SPEC = ConstraintSpec(
    name="angular_speed",
    summary="bound the angular speed of the frame",
    subject=True,
    args=(ArgSpec("max", "angular_speed", "the largest angular speed", range=POSITIVE),),
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-C",
    rate=True,
)


def lower(c, ctx) -> Rows:
    return speed_rows(c, ctx, ctx.frame(c.frame).Jw)
