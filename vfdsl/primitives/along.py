"""Move along a line (paper II-B.3, eqs. 7-10).

Keep the frame origin within ``eps`` of the line L(s) = L0 + l s:  delta_p = p - P_cl (closest point),
u_p = projection of (delta_p + dx_p) on the plane normal to l,  || u_p || <= eps, approximated by the n-gon
u_i = R3 [cos a_i, sin a_i, 0], R3 = [v1 v2 l] (eq. 8): rows u_i . (delta_p + dx_p) <= eps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from vfdsl.compiler.geometry import polygon_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="along",
    summary="keep the frame origin within `within` of a line",
    subject=True,
    args=(ArgSpec("line", "line", "the line to move along"),),
    tolerance="length", default_tolerance=1e-5,
    resolution="polygon",
    source="Li, Kapoor & Taylor 2005, II-B.3, eqs. (7)-(10)",
    metric="length", drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    line = ctx.line(c.args["line"])
    return along_line(ctx.frame(c.frame), line.point, line.direction, c.tolerance, c.resolution[0])


def along_line(frame, point, direction, eps, n) -> Rows:
    """Polygon rows keeping ``frame``'s origin within eps of the line (point, unit direction)."""
    delta = frame.p - point                      # its component along the line is ignored by the rows
    return facets(polygon_directions(direction, n), delta, eps, frame.Jv)
