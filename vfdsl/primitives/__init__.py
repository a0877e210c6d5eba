"""Constraint primitives, one module each: its math in the docstring, its ``SPEC`` (signature) and its ``lower()``
(registered with the compiler here)."""

from vfdsl.primitives import (
                              above,
                              along,
                              angular_speed,
                              cone,
                              follows,
                              inside_mesh,
                              joint_limits,
                              joint_speed,
                              keeps_direction,
                              near_plane,
                              on_plane,
                              outside_mesh,
                              outside_sphere,
                              passes_through,
                              rotates_around,
                              speed,
                              stays_at,
                              tilt_at_most,
                              within_distance,
                              within_sphere,
)
from vfdsl.compiler import registry
from vfdsl.primitives.spec import ConstraintSpec

_MODULES = (stays_at, keeps_direction, along, rotates_around, above, on_plane, follows, cone, passes_through,
            within_distance, joint_limits, joint_speed, speed, angular_speed,
            within_sphere, outside_sphere, near_plane, tilt_at_most, outside_mesh, inside_mesh)

CONSTRAINTS: dict[str, ConstraintSpec] = {m.SPEC.name: m.SPEC for m in _MODULES}

for _module in _MODULES:
    registry.register_constraint(_module.SPEC, _module.lower)
