"""Stay in a band around a plane: a symmetric on_plane (paper II-B.5, eqs. 16-17, both sides).

Keep the frame origin within w of a plane (point P, unit normal d), on either side:
|d . (delta_p + dx_p)| <= w, delta_p = p - P, as two rows

    d . (delta_p + dx_p) >= -w,   -d . (delta_p + dx_p) >= -w
    ->   H = [d^T 0; -d^T 0],  h = [-w; -w] - H delta.

Exact (planes need no polytope); the sign of d does not matter.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.rows import Rows, lower_bounds
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import SIZE, ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="near_plane",
    summary="keep the frame origin within `half_width` of a plane, on either side",
    subject=True,
    args=(ArgSpec("plane", "plane", "the band's middle plane"),
          ArgSpec("half_width", "length", "the largest distance from the plane, either side", range=SIZE)),
    source="Li, Kapoor & Taylor 2005, II-B.5, eqs. (16)-(17), made symmetric",
    metric="length", row_unit="m", stated_by=("length", "half_width"), drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    plane = ctx.plane(c.args["plane"])
    d = plane.normal
    w = ctx.scalar(c.args["half_width"])
    depth = ca.dot(d, f.p - plane.point)
    return lower_bounds(ca.vertcat(d.T @ f.Jv, -d.T @ f.Jv), ca.vertcat(-w - depth, -w + depth),
                        ["not below band", "not above band"])
