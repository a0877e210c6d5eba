"""Stay at a point (paper II-B.1, eqs. 2-4).

Keep the frame origin within ``eps`` of a target point P:  || delta_p + dx_p || <= eps,  delta_p = p - P.
The ball is approximated by the n x m sphere polytope u_ij = [cos a_i cos b_j, cos a_i sin b_j, sin a_i],
a_i = 2 pi i / n, b_j = 2 pi j / m, with repeated directions removed (erratum 3); each facet gives
u . (delta_p + dx_p) <= eps, i.e. H = -u, h = -eps - H delta (erratum 1).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from vfdsl.compiler.geometry import sphere_directions
from vfdsl.compiler.rows import Rows, facets
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="stays_at",
    summary="keep the frame origin within `within` of a point",
    subject=True,
    args=(ArgSpec("target", "point", "the point to stay at"),),
    tolerance="length", default_tolerance=1e-5,
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-B.1, eqs. (2)-(4)",
    metric="length", reference_point="target", error_is_distance=True,
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    f = ctx.frame(c.frame)
    delta = f.p - ctx.point(c.args["target"])
    return facets(ca.DM(sphere_directions(*c.resolution)), delta, c.tolerance, f.Jv)
