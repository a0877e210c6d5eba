"""Objective terms, one module each: its math in the docstring and its ``SPEC`` (signature)."""

from vfdsl.objectives import centering, damping, direction_change, distance, track
from vfdsl.primitives.spec import ObjectiveSpec

_MODULES = (track, distance, direction_change, damping, centering)

OBJECTIVES: dict[str, ObjectiveSpec] = {m.SPEC.name: m.SPEC for m in _MODULES}
