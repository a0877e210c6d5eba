"""What a constraint bounds: its stated size (a tolerance, or a distance or speed argument) and the polytope behind
its rows (:mod:`vfdsl.compiler.polytope`), whose circumradius times the size is the guaranteed bound."""

from __future__ import annotations

import math

from vfdsl.compiler.polytope import PolytopeGeometry, geometry
from vfdsl.errors import VfError
from vfdsl.ir import model as ir
from vfdsl.ir.constraints import value_of
from vfdsl.primitives import CONSTRAINTS


def constraint_geometry(c: ir.Constraint) -> PolytopeGeometry | None:
    """The polytope behind a constraint's rows, or None when its rows are exact (planes, joint bounds)."""
    shape = CONSTRAINTS[c.primitive].resolution_shape(c.args)
    if shape is None or c.resolution is None:
        return None
    return geometry(shape, tuple(c.resolution))


def admitted(c: ir.Constraint, task: ir.Task, e: float) -> float:
    """The largest true error the constraint's rows admit when they hold within e (``ConstraintSpec.admitted``:
    a cone's rows bound a sine), e itself when they measure the error; e where the value it needs is not known
    before the controller runs (a capture of a frame), and e unbounded (a polytope that does not enclose the origin)."""
    rule = CONSTRAINTS[c.primitive].admitted
    if rule is None or not math.isfinite(e):
        return e
    try:
        return rule(c, task, e)
    except VfError:
        return e


def guaranteeing(c: ir.Constraint, task: ir.Task, factor: float, size: float) -> float:
    """The stated size s whose rows (their polytope's circumradius ``factor``) admit at most ``size``:
    admitted(factor s) = size, by bisection (admitted grows with its argument)."""
    low, high = 0.0, size / factor
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if admitted(c, task, factor * mid) <= size else (low, mid)
    return low


def stated_size(c: ir.Constraint, task: ir.Task) -> tuple[str, float] | None:
    """(kind, SI value) of what the constraint bounds: its tolerance, or its distance or speed argument."""
    spec = CONSTRAINTS[c.primitive]
    if spec.stated_by is not None:
        kind, name = spec.stated_by
        return kind, float(value_of(c.args[name], task).value)
    if c.tolerance is None:
        return None
    return spec.tolerance, float(c.tolerance)
