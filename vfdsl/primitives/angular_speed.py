"""Angular speed limit of a frame:  || dx_r || <= w_max dt, by the n x m sphere polytope."""

from __future__ import annotations

from typing import TYPE_CHECKING

from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import SIZE, ArgSpec, ConstraintSpec
from vfdsl.primitives.speed import speed_rows

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="angular_speed",
    summary="bound the angular speed of the frame",
    subject=True,
    args=(ArgSpec("max", "angular_speed", "the largest angular speed", range=SIZE),),
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-C",
    rate=True,
    metric="angular_speed", row_unit="rad", stated_by=("angular_speed", "max"),
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    return speed_rows(c, ctx, ctx.frame(c.frame).Jw)
