"""What a constraint bounds: its stated size (a tolerance, or a distance or speed argument) and the polytope behind
its rows (:mod:`vfdsl.compiler.polytope`), whose circumradius times the size is the guaranteed bound."""

from __future__ import annotations

from vfdsl.compiler.polytope import PolytopeGeometry, geometry
from vfdsl.ir import model as ir
from vfdsl.ir.constraints import value_of
from vfdsl.primitives import CONSTRAINTS


def constraint_geometry(c: ir.Constraint) -> PolytopeGeometry | None:
    """The polytope behind a constraint's rows, or None when its rows are exact (planes, joint bounds)."""
    shape = CONSTRAINTS[c.primitive].resolution_shape(c.args)
    if shape is None or c.resolution is None:
        return None
    return geometry(shape, tuple(c.resolution))


def stated_size(c: ir.Constraint, task: ir.Task) -> tuple[str, float] | None:
    """(kind, SI value) of what the constraint bounds: its tolerance, or its distance or speed argument."""
    spec = CONSTRAINTS[c.primitive]
    if spec.stated_by is not None:
        kind, name = spec.stated_by
        return kind, float(value_of(c.args[name], task).value)
    if c.tolerance is None:
        return None
    return spec.tolerance, float(c.tolerance)
