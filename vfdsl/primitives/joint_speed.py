"""Joint speed limits:  |dq_i| <= fraction * qdot_max_i * dt, with qdot_max from the URDF."""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec, Range

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="joint_speed",
    summary="bound each joint's speed by a fraction of its URDF velocity limit",
    subject=False,
    args=(ArgSpec("fraction", "number", "fraction of the URDF velocity limit",
                  default=ir.ScalarValue(dimension="number", value=1.0),
                  range=Range(0.0, 1.0, low_open=True)),),
    source="Li, Kapoor & Taylor 2005, II-C (an upper bound on the incremental motion)",
    rate=True,
    metric="speed", row_unit="",
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    robot = ctx.robot
    step = ctx.scalar(c.args["fraction"]) * ca.DM(robot.velocity_limit) * ctx.dt
    return Rows(A=ca.SX.eye(robot.nq), lb=-step, ub=step, facets=list(robot.joint_names), bounds=True)
