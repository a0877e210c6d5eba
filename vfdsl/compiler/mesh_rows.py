"""Rows of a mesh fixture: the K nearest features of a triangle mesh to the tool, each a moving half-space.

The tool is a capsule: the segment from the subject frame's origin a to the ``shaft`` frame's origin b (a = b
for a point) with a ``radius`` r. Each tick the proximity query (:mod:`vfdsl.mesh.external`, C) gives, for up to
K features (faces, edges, vertices) of the mesh near the segment, the signed distance d_i (> 0 on the free side),
the segment parameter s_i of the closest point x_i = a + s_i (b - a), and the unit u_i from the feature toward
the free side at x_i, all in the mesh's frame (placed in the world by its pose, u_i -> R u_i). Each gives the
row (the paper's forbidden half-space on the feature's tangent plane, as ``outside_sphere``):

    u_i . (dx_i) >= -(d_i - r - margin),      dx_i = ((1 - s_i) J_a + s_i J_b) dq   (J: linear Jacobians)

d_i, s_i, u_i are data (the query's outputs, no derivative); the Jacobian is the frames'. A feature the segment
is on the wrong side of has d_i < 0, and its row asks to move back by |d_i| + r + margin. Features farther
than r + margin + reach give no row (d = +inf: the row 0 >= -inf always holds), so the number of rows is K
whatever the mesh, and the tick allocates nothing.

**Bounds.** Each row is exact to first order for the plane tangent at the feature: after a step dx with the row
held, the true clearance is >= margin - e with
- curvature: a concave wall of radius rho (inside a channel) comes closer than its tangent plane by |dx_t|^2 /
  (2 rho) for a tangential step dx_t;
- merged features: a feature whose direction is within 14 deg of a nearer one's (cos > 0.97, :data:`SIMILAR`)
  has no row of its own; the nearer row holds it to within 2 sin(7 deg) |dx| = 0.24 |dx|;
- features beyond reach: none can be reached in one tick when |dx| <= reach.
With |dx| <= v_max dt (a speed limit), e <= 0.24 v_max dt + (v_max dt)^2 / (2 rho): ``vfdsl check`` compares
the margin with it, and reach with v_max dt.

**K = 8.** The nearest features that are not merged have directions at least 14 deg apart: around a tool in a
channel they are the walls on every side (a ring of 6-8 within a half-turn of the closest wall, measured on
tasks/anatomy/channel.stl), and next to a bone the bone's face, its nearest edge and a nerve. K = 8 keeps them
all; the query cost grows with K (a list kept by insertion) and so do the solver's rows.
"""

from __future__ import annotations

import casadi as ca

from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, Range

K = 8
"""Rows per mesh fixture (see the module's docstring)."""
REACH = 5e-3
"""m: default reach, 5 mm (the motion of one tick at 5 m/s and 1 kHz)."""

MESH_ARGS = (
    ArgSpec("mesh", "mesh", "the mesh (a mesh param)"),
    ArgSpec("margin", "length", "clearance kept from the surface", range=Range(low=0.0)),
    ArgSpec("shaft", "frame", "the other end of the tool's segment (default: the frame itself, a point)",
            default="subject"),
    ArgSpec("radius", "length", "the tool's radius around the segment",
            default=ir.ScalarValue(dimension="length", value=0.0), range=Range(low=0.0)),
    ArgSpec("reach", "length", "features farther than radius + margin + reach get no row (at least the motion "
            "of one tick)", default=ir.ScalarValue(dimension="length", value=REACH), range=Range(low=0.0, low_open=True)),
)


def mesh_rows(c, ctx, side: float) -> Rows:
    """The K rows of ``c`` (outside_mesh: side = +1, the normals point to the free side; inside_mesh: -1)."""
    placed = ctx.mesh(c.args["mesh"], K)
    a_frame, b_frame = ctx.frame(c.frame), ctx.frame(c.args["shaft"].name)
    radius, margin, reach = (ctx.scalar(c.args[name]) for name in ("radius", "margin", "reach"))
    R, t = placed.R, placed.t
    a_local, b_local = R.T @ (a_frame.p - t), R.T @ (b_frame.p - t)
    cutoff = ca.vertcat(radius + margin + reach, side)
    d, s, u = placed.query.function(a_local, b_local, cutoff)
    U = R @ u                                                       # 3 x K, world
    rows, lbs = [], []
    for i in range(K):
        J = (1 - s[i]) * a_frame.Jv + s[i] * b_frame.Jv
        rows.append(U[:, i].T @ J)
        lbs.append(radius + margin - d[i])
    return Rows(A=ca.vertcat(*rows), lb=ca.vertcat(*lbs), ub=ca.SX(ca.DM.inf(K)),
                facets=[f"feature {i + 1}/{K}" for i in range(K)])
