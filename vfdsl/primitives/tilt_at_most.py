"""Tilt at most an angle from an axis: the tool axis stays inside a cone (cf. ``cone``, which holds a fixed angle).

Keep the tool axis l within the cone of half-angle gamma around the unit axis a:  g = cos gamma - l . a <= 0.
The step turns l by the rotation vector alpha = J_w dq:  d(l . a) = (alpha x l) . a = alpha . (l x a), so the
one exact row (a half-space of rotations, like ``above``, with no tolerance and no polytope) is

    (l x a)^T J_w dq >= cos gamma - l . a.

At l = a the gradient l x a is zero and the row reads 0 >= cos gamma - 1 < 0: inactive, as it should be (the
axis is the cone's centre). At l = -a it would read 0 >= cos gamma + 1 > 0, which no step can meet (the tool held
reversed, the row violated tick after tick): there (|l x a| <= PARALLEL, l . a < 0) the gradient is s k instead, k a
fixed unit normal to a: a turn by phi about k takes l . a from -1 to -cos phi, into the cone at phi = pi - gamma, so
s = (1 + cos gamma) / (pi - gamma) makes the row ask that whole turn, with the bound left as it is on either side
of the switch (phase 2's line search measures the bounds: a bound that jumped there, the angle pi - gamma for
1 + cos gamma, made its slope look steep and held the tool still). With s = 1 the row asked a turn of 1 + cos gamma,
~ (pi - gamma)^2 / 2: 0.15 mrad where 17.5 mrad were needed for gamma = 179 deg, and a tick without speed limits said
OPTIMAL with the tool still reversed. After the turn l x a points along k and the exact row takes over. ``check``
flags such a start (the true angle, not the rows).

Bound: a step that turns l by an angle phi about any axis and meets the row ends with
l' . a >= cos gamma - (1 - cos phi) - (phi - sin phi)  (Rodrigues' formula; |(k x l) . a|, |k x (k x l) . a| <= 1),
so the tilt passes gamma by at most arccos(cos gamma - phi^2/2 - phi^3/6) - gamma ~ phi^2 / (2 sin gamma) per
tick, and the next tick's row pulls it back.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import PARALLEL, plane_basis
from vfdsl.compiler.rows import Rows, lower_bounds
from vfdsl.ir import model as ir
from vfdsl.primitives.keeps_direction import angle_between
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec, Range

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context


def true_angle(c: ir.Constraint, ctx: Context):
    """max(0, angle(l, a) - gamma)."""
    angle = angle_between(ctx.frame(c.frame).axis, ctx.direction(c.args["axis"]))
    return ca.fmax(0, angle - ctx.scalar(c.args["angle"]))


SPEC = ConstraintSpec(
    name="tilt_at_most",
    summary="keep the tool axis within an angle of an axis (a cone it may move inside)",
    subject=True,
    args=(ArgSpec("axis", "direction", "the cone axis a"),
          ArgSpec("angle", "angle", "the largest tilt gamma from the axis",
                  range=Range(0.0, math.pi, low_open=True, high_open=True, unit="deg"))),
    source="the cone of Li, Kapoor & Taylor 2005, III-B, as an inequality",
    metric="angle", row_unit="", true_angle=true_angle, kept_angle="angle", angle_rows="cos",
    drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    a = ctx.direction(c.args["axis"])
    gamma = ctx.scalar(c.args["angle"])
    cross = ca.cross(f.axis, a)                          # d(l . a) = alpha . (l x a)
    reversed_ = (1 + ca.cos(gamma)) / (ca.pi - gamma) * plane_basis(a)[0]     # asks the turn pi - gamma about k
    gradient = ca.if_else(ca.logic_or(ca.norm_2(cross) > PARALLEL, ca.dot(f.axis, a) >= 0), cross, reversed_)
    return lower_bounds(gradient.T @ f.Jw, ca.cos(gamma) - ca.dot(f.axis, a), ["tilt"])
