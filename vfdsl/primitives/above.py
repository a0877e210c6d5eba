"""Forbidden half-space (paper II-B.5, eqs. 14-15; lecture "forbidden half space").

Keep the frame origin on the free side of a plane with unit normal d toward the free side:
delta_p = p - P_cl,  d . (delta_p + dx_p) >= 0  ->  H = [d^T 0], h = -H delta.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.rows import Rows, lower_bounds
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="above",
    summary="keep the frame origin on the free side of a plane (its normal points to the free side)",
    subject=True,
    args=(ArgSpec("plane", "plane", "the boundary plane, normal toward the allowed side"),),
    source="Li, Kapoor & Taylor 2005, II-B.5, eqs. (14)-(15)",
    metric="length", row_unit="m", drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    plane = ctx.plane(c.args["plane"])
    d = plane.normal
    return lower_bounds(d.T @ f.Jv, -ca.dot(d, f.p - plane.point), ["half-space"])
