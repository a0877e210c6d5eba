"""Rotate around an axis with a fixed angle: a cone (paper III-B, eqs. 22-23).

Keep the tool axis l_t at angle gamma from an axis l_a (a cone of half-angle gamma): the instantaneous
rotation axis w_d = R [cos gamma, sin gamma, 0]^T with d1 = l_t x l_a / ||.||, d2 = d1 x l_a / ||.||,
R = [d2, l_a/||l_a||, -d1] (eq. 22); delta_r = d1 sin gamma - l_t x l_a (eq. 23); then the
"rotate around a line" rows (eq. 13) about w_d. Beyond 90 deg (l_t . l_a < 0) |l_t x l_a| = sin theta is continued as
2 - sin theta (:func:`vfdsl.compiler.geometry.continued_sine`): the paper's delta_r = (sin gamma - sin theta) d1 is 0
on the opposite nappe (theta = 180 deg - gamma), where the rows held the tool reversed. Where l_t is along +-l_a, d1
(undefined) is a fixed normal to l_a: the paper's delta_r was 0 there, the tool held on the axis or reversed.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import continued_sine, normalize, plane_basis, turn_axis
from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.ir.constraints import value_of
from vfdsl.primitives.keeps_direction import angle_between
from vfdsl.primitives.rotates_around import around_axis
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec, Range

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context


def true_angle(c: ir.Constraint, ctx: Context):
    """| angle(l_t, l_a) - gamma |."""
    return ca.fabs(angle_between(ctx.frame(c.frame).axis, ctx.direction(c.args["axis"])) - ctx.scalar(c.args["angle"]))


def sine_admitted(gamma: float, e: float) -> float:
    """The largest |theta - gamma| with |s(theta) - sin gamma| <= e, s the continued sine (sin theta up to 90 deg,
    2 - sin theta beyond): what rows that hold (sin gamma - s(theta)) d1 within e admit of the angle. ~ e / cos gamma
    for small e, and ~ sqrt(2 e) at gamma = 90 deg (docs/primitives.md, note 8)."""
    high = math.sin(gamma) + e
    theta_max = math.asin(high) if high <= 1 else math.pi - math.asin(max(2 - high, -1.0))
    theta_min = math.asin(min(max(math.sin(gamma) - e, 0.0), 1.0))
    return max(theta_max - gamma, gamma - theta_min)


def admitted(c: ir.Constraint, task: ir.Task, e: float) -> float:
    """The angle error the rows admit at the cone's half-angle (its param's default for a param)."""
    return sine_admitted(float(value_of(c.args["angle"], task).value), e)


SPEC = ConstraintSpec(
    name="cone",
    summary="keep the tool axis at a fixed angle from an axis",
    subject=True,
    args=(ArgSpec("axis", "direction", "the cone axis l_a"),
          ArgSpec("angle", "angle", "the cone half-angle gamma",
                  range=Range(0.0, math.pi / 2, low_open=True, high_open=True, unit="deg"))),
    tolerance="angle", default_tolerance=1e-3,
    resolution="polygon",
    source="Li, Kapoor & Taylor 2005, III-B, eqs. (22)-(23)",
    metric="angle", true_angle=true_angle, kept_angle="angle", drawn_around_frame=True, admitted=admitted,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    l_t = f.axis
    l_a = ctx.direction(c.args["axis"])
    gamma = ctx.scalar(c.args["angle"])
    cross = ca.cross(l_t, l_a)
    d1 = turn_axis(cross, plane_basis(l_a)[0])
    d2 = normalize(ca.cross(d1, l_a))
    w_d = ca.cos(gamma) * d2 + ca.sin(gamma) * l_a          # eq. 22: R [cos g, sin g, 0]^T, R = [d2, l_a, -d1]
    delta_r = d1 * ca.sin(gamma) - continued_sine(cross, ca.dot(l_t, l_a), d1)      # eq. 23
    return around_axis(f, w_d, c.tolerance, c.resolution[0], delta_r, tilt=d1)
