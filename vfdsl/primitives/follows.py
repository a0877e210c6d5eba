"""Follow a curve (paper III-A, eqs. 19-20).

Every tick, find the point P_c of the curve closest to the anchor frame's origin and the unit tangent l_c
there; shift P_c by ``shift`` (given in the curve's own frame, e.g. 100 mm along the plate normal for the
tool shaft) and apply "move along a line" (II-B.3) with the line through P_c + shift along l_c.

On a polyline (degree 1) one more row keeps the frame on its segment: with b and a the room behind and ahead
of P_c on the segment (inf past the polyline's ends), -b <= l_c . (p + dx_p - P_c - shift) <= a, so the frame
stops at a corner instead of running past it along the old segment; it turns the corner when pushed toward
the next segment (the closest point moves there, ties going to the later segment).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.primitives.along import along_line
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="follows",
    summary="keep the frame origin within `within` of a curve (closest point and tangent every tick)",
    subject=True,
    args=(ArgSpec("curve", "curve", "the b-spline to follow"),
          ArgSpec("shift", "vector", "offset of the followed copy of the curve, in the curve's frame",
                  default=ir.VectorValue(xyz=[0.0, 0.0, 0.0])),
          ArgSpec("anchor", "frame", "the frame whose closest point on the curve is used", default="subject")),
    tolerance="length", default_tolerance=1e-5,
    resolution="polygon",
    source="Li, Kapoor & Taylor 2005, III-A, eqs. (19)-(21)",
    metric="length",
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    curve = ctx.curve(c.args["curve"])
    anchor = ctx.frame(c.args["anchor"].name)
    found = ctx.closest_point(c.args["curve"], c.args["anchor"].name, curve, anchor.p)
    frame = ctx.frame(c.frame)
    point = found.point + curve.R @ ctx.vector(c.args["shift"])     # a param shift too (read in the curve's frame)
    rows = along_line(frame, point, found.tangent, c.tolerance, c.resolution[0])
    if found.behind is None:
        return rows
    progress = ca.dot(found.tangent, frame.p - point)
    return Rows(A=ca.vertcat(rows.A, found.tangent.T @ frame.Jv), lb=ca.vertcat(rows.lb, -found.behind - progress),
                ub=ca.vertcat(rows.ub, found.ahead - progress), facets=rows.facets + ["segment"])
