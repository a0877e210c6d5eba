"""Keep out of a ball: a forbidden sphere around a structure at risk.

Keep the frame origin p at least r from a center c:  || p + dx_p - c || >= r. Every tick the ball is
replaced by its tangent plane at the sphere point closest to p, n = (p - c) / || p - c ||, and p kept
on its outer side (a moving forbidden half-space, as ``above``):

    n . (p - c + dx_p) >= r    ->    n J_v dq >= r - n . (p - c)

The row is conservative: || x || >= n . x, so a step that keeps it leaves p outside the ball (up to the
first-order model of the kinematics); motion along the plane slides around the ball. At rest it reads
|| p - c || >= r. When no coordinate of p - c exceeds COINCIDENT (within_sphere), n is the frame's tool
axis (from the tip toward the handle on the shipped robots): the row then asks to retract along it by r.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from vfdsl.compiler.rows import Rows, lower_bounds
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ConstraintSpec
from vfdsl.primitives.within_sphere import BALL, tangent_plane

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="outside_sphere",
    summary="keep the frame origin out of a ball (its tangent plane at the closest point every tick)",
    subject=True,
    args=BALL,
    source="Li, Kapoor & Taylor 2005, II-B.5 (a forbidden half-space on the sphere's tangent plane)",
    metric="length", row_unit="m",
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    a, height, r = tangent_plane(c, ctx)
    return lower_bounds(a, r - height, ["tangent plane"])
