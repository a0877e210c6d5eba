"""The signature the mesh primitives share (:mod:`~vfdsl.primitives.outside_mesh`,
:mod:`~vfdsl.primitives.inside_mesh`); their rows are :func:`vfdsl.compiler.mesh_rows.mesh_rows`."""

from __future__ import annotations

from vfdsl import limits
from vfdsl.compiler.mesh_rows import REACH
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, Range

MESH_ARGS = (
    ArgSpec("mesh", "mesh", "the mesh (a mesh param)"),
    ArgSpec("margin", "length", "clearance kept from the surface", range=Range(low=0.0, high=limits.ROW_VALUE)),
    ArgSpec("shaft", "frame", "the other end of the tool's segment (default: the frame itself, a point)",
            default="subject"),
    ArgSpec("radius", "length", "the tool's radius around the segment",
            default=ir.ScalarValue(dimension="length", value=0.0), range=Range(low=0.0, high=limits.ROW_VALUE)),
    ArgSpec("reach", "length", "features farther than radius + margin + reach get no row (at least the motion "
            "of one tick)", default=ir.ScalarValue(dimension="length", value=REACH),
            range=Range(low=0.0, low_open=True, high=limits.ROW_VALUE)),
)
