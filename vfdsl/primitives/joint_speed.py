"""Joint speed limits:  |dq_i| <= fraction * qdot_max_i * dt, with qdot_max from the URDF."""

from vfdsl.ir import model as ir
from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="joint_speed",
    summary="bound each joint's speed by a fraction of its URDF velocity limit",
    subject=False,
    args=(ArgSpec("fraction", "number", "fraction of the URDF velocity limit",
                  default=ir.ScalarValue(dimension="number", value=1.0)),),
    source="Li, Kapoor & Taylor 2005, II-C (an upper bound on the incremental motion)",
)
