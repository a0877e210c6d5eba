"""Rotate around a line (paper II-B.4, eqs. 11-13).

Keep the tool axis l_t perpendicular to a direction w_d (the tool sweeps the plane Pi normal to w_d):
l_Pi = normalized projection of l_t on Pi,  delta_r = l_Pi x l_t,  u_r = projection of (delta_r + dx_r) on Pi,
|| u_r || <= eps with the n-gon of R4 = [v1 v2 w_d]. Erratum 2: the rows act on (delta_r + dx_r).
With the tool along w_d (|l_t x w_d| <= PARALLEL) the projection has no direction: l_Pi is then the fixed normal
v1 of w_d, and |delta_r| = 1 (before, l_Pi and delta_r were 0: every row held at dq = 0, the fixture off).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import plane_basis, polygon_directions, turn_axis
from vfdsl.compiler.rows import Rows, facets
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context


def true_angle(c: ir.Constraint, ctx: Context):
    """| asin(l_t . w) |: the tool axis' angle out of the plane normal to w."""
    return ca.fabs(ca.asin(ca.fmin(1, ca.fmax(-1, ca.dot(ctx.frame(c.frame).axis, ctx.direction(c.args["axis"]))))))


SPEC = ConstraintSpec(
    name="rotates_around",
    summary="keep the tool axis perpendicular to an axis, so the tool rotates around it",
    subject=True,
    args=(ArgSpec("axis", "direction", "the rotation axis w_d"),),
    tolerance="angle", default_tolerance=1e-3,
    resolution="polygon",
    source="Li, Kapoor & Taylor 2005, II-B.4, eqs. (11)-(13); DESIGN erratum 2",
    metric="angle", true_angle=true_angle, drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    return around_axis(ctx.frame(c.frame), ctx.direction(c.args["axis"]), c.tolerance, c.resolution[0])


def around_axis(frame, w, eps, n, delta_r=None, tilt=None) -> Rows:
    """Polygon rows (normal to w) on delta_r + dx_r, its facet n/n along ``tilt`` (the unit direction of delta_r,
    normal to l_t and w); delta_r defaults to l_Pi x l_t (eq. 11), along l_Pi x w."""
    if delta_r is None:      # the projection's length is |l_t x w|: none along w, where a fixed normal turns the tool
        l_pi = turn_axis(frame.axis - ca.dot(frame.axis, w) * w, plane_basis(w)[0])
        delta_r, tilt = ca.cross(l_pi, frame.axis), ca.cross(l_pi, w)
    return facets(polygon_directions(w, n, first=tilt), delta_r, eps, frame.Jw)
