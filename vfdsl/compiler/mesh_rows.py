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
whatever the mesh, and the tick allocates nothing; but an end of the segment on the forbidden side always keeps
its nearest feature, however far (a tool outside a keep-in channel, deep inside a keep-out volume): a violated
fixture is never without a row.

**Which features.** The query (:mod:`vfdsl.mesh.external`; its C source states the answer exactly, and
:func:`vfdsl.mesh.brute.features` computes the same from every triangle) takes, for each part of the segment
(its start, its end, the points between), every triangle's closest point to that part within the cutoff; per
part, in order of distance, a feature whose direction is within 14 deg (cos > 0.97) of one kept before it is
merged into it (a feature seen through several triangles, a patch of one wall); the K rows are the nearest
kept feature of each part, then the nearest of the other kept ones.

**Bounds.** Each row is exact to first order for the plane tangent at its feature: after a step dx with the rows
held, the true clearance is >= margin - e with
- curvature: a concave wall of radius rho (inside a channel) comes closer than its tangent plane by |dx_t|^2 /
  (2 rho) for a tangential step dx_t;
- merged features: a feature without a row of its own was merged, once, into a nearer kept feature within 14 deg
  of it; when that one is a row, it holds the feature to within 2 sin(7 deg) |dx| = 0.24 |dx| at the same point
  of the segment. Between the ends the two may be at different points of the shaft, which a turn of the shaft
  moves differently: ``vfdsl check`` keeps 0.48 |dx| (2 sin(14 deg), the figure of the query's earlier walk,
  which merged up to twice) for this term, a margin for that, not a proof;
- features beyond reach: none can be reached in one tick when |dx| <= reach;
- features cut: a kept feature that is not among the K rows (they are the nearest) has no row; this is not
  bounded by the formula below, only measured (the closed-loop tests and the K measurement below).
With |dx| <= v_max dt (a speed limit), e <= 0.48 v_max dt + (v_max dt)^2 / (2 rho): ``vfdsl check`` compares
the margin with it (VF906), and reach with v_max dt.

**K = 8.** Measured on tasks/sinus_channel.vf (``benchmarks/mesh_k.py``), pushing the shaft into the channel's
wall in four directions for 250 ticks each: K = 4, 8 and 16 give the same smallest clearance (0.482 mm for a
0.5 mm margin, brute force; 0.488 mm with the query's earlier walk), although the query keeps up to 86 features
within reach over the three parts after merging (83 at the 99th percentile, 68 at the median): the rows that
bind are the nearest. K = 8 is twice the smallest K that held, for a corner where two walls bind at both ends of
the shaft (3 parts x 2 walls, and 2 more); each row costs the solver, K = 16 made the tick 10% slower.
"""

from __future__ import annotations

import casadi as ca

from vfdsl.compiler.rows import Rows

K = 8
"""Rows per mesh fixture (see the module's docstring)."""
REACH = 2e-3
"""m: default reach, 2 mm (the motion of one tick at 200 mm/s and 100 Hz; ``vfdsl check`` compares it with the
speed limits)."""


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
