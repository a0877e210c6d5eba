"""Remote center of motion through a port (lecture, slide 46).

Keep the tool-axis line through the frame origin p with direction l_t within ``eps`` of the port point c:
the perpendicular offset e = (I - l_t l_t^T)(c - p) after the step, linearized in both dp and dr,
bounded by an n-gon in the plane normal to l_t.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import polygon_directions, skew
from vfdsl.compiler.rows import Rows, facets
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="passes_through",
    summary="keep the tool axis line within `within` of a port point (remote center of motion)",
    subject=True,
    args=(ArgSpec("port", "point", "the entry port c"),),
    tolerance="length", default_tolerance=1e-5,
    resolution="polygon",
    source="Taylor, lecture notes, slide 46",
    metric="length", reference_point="port", drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    l = f.axis
    r = ctx.point(c.args["port"]) - f.p
    w = ca.cross(r, l)                                       # |w| = distance from the port to the tool line
    J_w = skew(l) @ f.Jv - skew(r) @ skew(l) @ f.Jw          # d w = l x dp + r x (dr x l)
    return facets(polygon_directions(l, c.resolution[0]), w, c.tolerance, J_w)
