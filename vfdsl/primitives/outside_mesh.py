"""Keep out of a mesh: a point, or the tool's shaft (a capsule), stays ``margin`` clear of anatomy.

The subject frame's origin a, or the segment a b to the ``shaft`` frame with a ``radius`` r, keeps a clearance of
at least ``margin`` from a triangle mesh whose normals point to the free side (outward for a closed structure
such as a nerve or a bone). Each of the K nearest features i of the mesh gives a forbidden half-space on its
tangent plane, linearized as the paper's plane primitive:

    u_i . ((1 - s_i) J_a + s_i J_b) dq >= -(d_i - r - margin)

with d_i the signed distance of the capsule's axis to the feature, s_i where on the segment it is closest, and u_i
the unit from the feature toward the free side (:mod:`vfdsl.compiler.mesh_rows`, which also gives K, the
features kept and the bound of one tick's linearization error).
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
    name="outside_mesh",
    summary="keep the frame origin, or the capsule to a shaft frame, at least a margin outside a triangle mesh",
    subject=True,
    args=MESH_ARGS,
    source="Li, Kapoor & Taylor 2005, II-B.5 (forbidden half-spaces), on the K nearest features of a mesh "
           "(Li & Taylor, ICRA 2004)",
    metric="length", row_unit="",
)


def lower(c: ir.Constraint, ctx: Context) -> Rows:
    return mesh_rows(c, ctx, side=1.0)
