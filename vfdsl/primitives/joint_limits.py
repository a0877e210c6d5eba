"""Joint position limits (lecture, slide 44):  q_lo - q <= dq <= q_hi - q."""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="joint_limits",
    summary="keep every joint within its URDF limits",
    subject=False,
    source="Taylor, lecture notes, slide 44",
    metric="length", row_unit="",
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    robot = ctx.robot
    limited = [i for i in range(robot.nq) if np.isfinite(robot.lower[i]) and np.isfinite(robot.upper[i])]
    A = ca.SX(ca.DM.eye(robot.nq)[limited, :])
    return Rows(A=A, lb=ca.DM(robot.lower[limited]) - ctx.q[limited], ub=ca.DM(robot.upper[limited]) - ctx.q[limited],
                facets=[robot.joint_names[i] for i in limited], bounds=len(limited) == robot.nq)
