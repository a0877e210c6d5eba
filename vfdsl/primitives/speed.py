"""Cartesian speed limit of a frame origin:  || dx_p || <= v_max dt, by the n x m sphere polytope."""

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
    name="speed",
    summary="bound the linear speed of the frame origin",
    subject=True,
    args=(ArgSpec("max", "speed", "the largest speed", range=SIZE),),
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-C",
    rate=True,
    metric="speed", row_unit="m", stated_by=("speed", "max"),
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    return speed_rows(c, ctx, ctx.frame(c.frame).Jv)


def speed_rows(c, ctx, J) -> Rows:
    """Sphere-polytope rows || J dq || <= max dt (J: the linear or the angular block of the frame Jacobian)."""
    return facets(ca.DM(sphere_directions(*c.resolution)), ca.DM.zeros(3), ctx.scalar(c.args["max"]) * ctx.dt, J)
