"""Cartesian speed limit of a frame origin:  || dx_p || <= v_max dt, by the n x m sphere polytope."""

from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="speed",
    summary="bound the linear speed of the frame origin",
    subject=True,
    args=(ArgSpec("max", "speed", "the largest speed"),),
    resolution="sphere",
    source="Li, Kapoor & Taylor 2005, II-C",
)
