"""Maintain a direction (paper II-B.2, eqs. 5-6).

Keep the tool axis l_t along a direction l_d:  delta_r = l_d x l_t,  || delta_r + dx_r || <= eps; beyond 90 deg
(l_d . l_t < 0) the length of delta_r is 2 - sin theta instead of sin theta, along the same axis (a fixed normal to
l_t where the two are opposite): the paper's sine falls back to 0 at 180 deg, where the rows would hold at dq = 0
with the tool reversed (:func:`vfdsl.compiler.geometry.continued_sine`).
The paper's 3-D polytope also bounds the roll about the tool axis by eps per tick (erratum 4), which pins
tool roll; the default is roll-free: only the two components of (delta_r + dx_r) normal to l_t are bounded
(an n-gon in the plane normal to l_t). ``pin_roll = true`` gives the paper's n x m sphere form.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import continued_sine, plane_basis, polygon_directions, sphere_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec, flag

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context


def angle_between(a, b):
    """The angle between two vectors, exact at 0 and 180 deg (a cross product's length alone is sin(angle))."""
    return ca.atan2(ca.norm_2(ca.cross(a, b)), ca.dot(a, b))


def true_angle(c: ir.Constraint, ctx: Context):
    """angle(l_t, l_d): the rows' cross product shows no error for an axis pointing the opposite way."""
    return angle_between(ctx.frame(c.frame).axis, ctx.direction(c.args["direction"]))


SPEC = ConstraintSpec(
    name="keeps_direction",
    summary="keep the tool axis along a direction (roll-free unless pin_roll = true)",
    subject=True,
    args=(ArgSpec("direction", "direction", "the direction the tool axis keeps"),
          ArgSpec("pin_roll", "flag", "also bound roll about the tool axis (the paper's 3-D form)",
                  default=ir.FlagValue(value=False))),
    tolerance="angle", default_tolerance=1e-3,
    resolution=lambda args: "sphere" if flag(args, "pin_roll") else "polygon",
    source="Li, Kapoor & Taylor 2005, II-B.2, eqs. (5)-(6); DESIGN erratum 4",
    metric="angle", true_angle=true_angle, kept_angle=0.0, drawn_around_frame=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    l_d = ctx.direction(c.args["direction"])
    delta_r = continued_sine(ca.cross(l_d, f.axis), ca.dot(l_d, f.axis), plane_basis(f.axis)[0])     # eq. 5
    if flag(c.args, "pin_roll"):
        U = ca.DM(sphere_directions(*c.resolution))
    else:
        U = polygon_directions(f.axis, c.resolution[0])
    return facets(U, delta_r, c.tolerance, f.Jw)
