"""Objective terms, one module each: its math in the docstring, its ``SPEC`` (signature) and its ``lower()``
(registered with the compiler here)."""

from vfdsl.compiler import registry
from vfdsl.objectives import centering, damping, direction_change, distance, teleop, track
from vfdsl.primitives.spec import ObjectiveSpec

_MODULES = (track, teleop, distance, direction_change, damping, centering)

OBJECTIVES: dict[str, ObjectiveSpec] = {m.SPEC.name: m.SPEC for m in _MODULES}

for _module in _MODULES:
    registry.register_objective(_module.SPEC, _module.lower)
