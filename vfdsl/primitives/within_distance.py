"""Stay within a distance of a point (lecture, "keep tool tip near a point", slide 44).

|| p + dx_p - P || <= r, approximated by the n x m sphere polytope (as stays_at with eps = r).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import sphere_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import SIZE, ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="within_distance",
    summary="keep the frame origin at most `distance` from a point",
    subject=True,
    args=(ArgSpec("center", "point", "the goal point"),
          ArgSpec("distance", "length", "the largest allowed distance", range=SIZE)),
    resolution="sphere",
    source="Taylor, lecture notes, slide 44",
    metric="length", row_unit="m", stated_by=("length", "distance"), reference_point="center",
    error_is_distance=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    delta = f.p - ctx.point(c.args["center"])
    return facets(ca.DM(sphere_directions(*c.resolution)), delta, ctx.scalar(c.args["distance"]), f.Jv)
