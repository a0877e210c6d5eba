"""Stay inside a closed mesh: a point, or the tool's shaft (a capsule), keeps ``margin`` from the walls of a
working channel or a safe volume.

The mesh is closed with outward normals (``vfdsl check`` says when it is not); the free side is inside, opposite
the normals. As ``outside_mesh``, each of the K nearest features i of the wall gives a half-space on its tangent
plane:

    u_i . ((1 - s_i) J_a + s_i J_b) dq >= -(d_i - r - margin)

with u_i now pointing from the wall into the volume, and d_i < 0 for a capsule axis that went through the wall
(its row asks back in). Inside a curved channel the tangent plane is not conservative: the wall of radius rho
comes closer by |dx_t|^2 / (2 rho) for a tangential step (:mod:`vfdsl.compiler.mesh_rows` gives the bound).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from vfdsl.compiler.mesh_rows import mesh_rows
from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.primitives.mesh_args import MESH_ARGS
from vfdsl.primitives.spec import ConstraintSpec

if TYPE_CHECKING:
    from vfdsl.compiler.context import Context

SPEC = ConstraintSpec(
    name="inside_mesh",
    summary="keep the frame origin, or the capsule to a shaft frame, at least a margin inside a closed mesh",
    subject=True,
    args=MESH_ARGS,
    source="Li & Taylor, ICRA 2004 (working volume from anatomy); half-spaces as Li, Kapoor & Taylor 2005, II-B.5",
    metric="length", row_unit="",
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    return mesh_rows(c, ctx, side=-1.0)
