"""Confine to a plane (paper II-B.5, eqs. 16-17).

Keep the frame origin on a plane, within ``eps`` on the free side:
0 <= d . (delta_p + dx_p) <= eps  ->  H = [d^T 0; -d^T 0], h = [0; -eps] - H delta.
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
    name="on_plane",
    summary="keep the frame origin on a plane, at most `within` above it",
    subject=True,
    args=(ArgSpec("plane", "plane", "the plane, normal toward the free side"),),
    tolerance="length", default_tolerance=1e-5,
    source="Li, Kapoor & Taylor 2005, II-B.5, eqs. (16)-(17)",
    metric="length", drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    plane = ctx.plane(c.args["plane"])
    d = plane.normal
    depth = ca.dot(d, f.p - plane.point)
    return lower_bounds(ca.vertcat(d.T @ f.Jv, -d.T @ f.Jv), ca.vertcat(-depth, -c.tolerance + depth),
                        ["not below", "not above tolerance"])
