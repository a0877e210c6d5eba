"""Shapes: literal values -> SI IR values, checking that each has the shape its kind needs.

A point or vector is 3 lengths, a direction 3 plain numbers (not all zero; normalized here), a line a
point and a direction, a plane a point and a normal, a pose a translation and roll-pitch-yaw angles, a curve
a degree (1 for a polyline) and at least degree + 1 points, no two consecutive points closer than twice the
spacing of the compiler's closest-point samples (:mod:`vfdsl.compiler.curve`), and not so long that it needs
more than ``limits.CURVE_SAMPLES`` samples. Composite literals are written as calls:
``line([0, 0, 0], [0, 0, 1])``, ``plane(point = [0, 0, 5] mm, normal = [0, 0, 1])``,
``pose(translation = [..], rpy = [..] deg)``, ``bspline(points = [[..], [..], ...])``.
"""

from __future__ import annotations

import math
from typing import Callable

from vfdsl.compiler.admissible import MIN_DIRECTION_NORM
from vfdsl.compiler.curve import MIN_SAMPLES, SAMPLE_SPACING
from vfdsl.errors import VfError, a_or_an, non_finite_name
from vfdsl.ir import model as ir
from vfdsl import limits
from vfdsl import units as u
from vfdsl.passes.calls import bind_arguments
from vfdsl.primitives.spec import SCALAR_DIMENSIONS
from vfdsl.syntax import ast

# A resolver for names that appear inside composite literals: returns the constant bound to that name.
ConstLookup = Callable[[ast.NameRef, str], ir.Value]

_COMPOSITES = {
    "line": (("point", "point"), ("direction", "direction")),
    "plane": (("point", "point"), ("normal", "direction")),
    "pose": (("translation", "vector"), ("rpy", "rpy")),
}
_WRITE_AS = {
    "point": "[x, y, z] with a length unit, e.g. [0, 0, -10] mm",
    "vector": "[x, y, z] with a length unit, e.g. [0, 0, 100] mm",
    "direction": "[x, y, z] plain numbers, e.g. [0, -0.2, 1]",
    "line": "line(point = [x, y, z], direction = [dx, dy, dz])",
    "plane": "plane(point = [x, y, z], normal = [nx, ny, nz])",
    "pose": "pose(translation = [x, y, z], rpy = [roll, pitch, yaw])",
    "curve": "bspline(points = [[x, y, z], ...]) or a list of points from the scene",
    "flag": "true or false",
}


def describe_kind(kind: str) -> str:
    return a_or_an(kind.replace("_", " "))


class LiteralReader:
    """Reads literal AST values in one unit context (a file's ``units`` statement)."""

    def __init__(self, units: u.DefaultUnits, lookup: ConstLookup):
        self.units = units
        self.lookup = lookup

    def read(self, value: ast.Value, kind: str, curve_degree: int | None = None) -> ir.Value:
        if isinstance(value, ast.NameRef):
            return self.lookup(value, kind)
        if kind in ("point", "vector"):
            xyz = self.numbers3(value, u.LENGTH, kind)
            return ir.PointValue(xyz=xyz) if kind == "point" else ir.VectorValue(xyz=xyz)
        if kind == "direction":
            return ir.DirectionValue(xyz=self._direction(value))
        if kind == "rpy":
            return ir.VectorValue(xyz=self.numbers3(value, u.ANGLE, "rpy"))
        if kind in _COMPOSITES:
            return self._composite(value, kind)
        if kind == "curve":
            return self._curve(value, curve_degree)
        if kind == "flag":
            if not isinstance(value, ast.Bool):
                raise self._wrong(value, kind)
            return ir.FlagValue(value=value.value)
        if kind in SCALAR_DIMENSIONS:
            return ir.ScalarValue(dimension=kind, value=self.scalar(value, SCALAR_DIMENSIONS[kind], kind))
        raise VfError(f"'{kind}' is not a value kind", value.span, code="E401")  # pragma: no cover - specs are fixed

    def scalar(self, value: ast.Value, dim: u.Dim, what: str) -> float:
        if isinstance(value, ast.NameRef):
            looked_up = self.lookup(value, what)
            assert isinstance(looked_up, ir.ScalarValue)
            return looked_up.value
        if not isinstance(value, ast.Quantity):
            raise VfError(f"expected {u.describe(dim)}, got {_what(value)}", value.span,
                          hint=f"write {u.example(dim)}", code="E401")
        return u.to_si(value.number, value.unit, dim, self.units, value.span)

    # -- helpers ---------------------------------------------------------------------------------------
    def _wrong(self, value: ast.Value, kind: str) -> VfError:
        return VfError(f"expected {describe_kind(kind)}, got {_what(value)}", value.span,
                       hint=f"write {_WRITE_AS[kind]}" if kind in _WRITE_AS else None, code="E401")

    def numbers3(self, value: ast.Value, dim: u.Dim, kind: str) -> list[float]:
        if not isinstance(value, ast.Vector):
            raise self._wrong(value, kind)
        if len(value.items) != 3:
            raise VfError(f"{describe_kind(kind)} needs 3 numbers, got {len(value.items)}", value.span,
                          hint=f"write {_WRITE_AS.get(kind, '[x, y, z]')}", code="E401")
        out = []
        for item in value.items:
            if not isinstance(item, ast.Quantity):
                raise (isinstance(item, ast.NameRef) and non_finite_name(item.name, item.span)
                       or VfError(f"expected a number, got {_what(item)}", item.span, code="E401"))
            unit = item.unit if item.unit is not None else value.unit
            out.append(u.to_si(item.number, unit, dim, self.units, item.span))
        return out

    def _direction(self, value: ast.Value) -> list[float]:
        if isinstance(value, ast.Vector) and value.unit is not None:
            raise VfError(f"a direction is plain numbers; remove the unit '{value.unit}'", value.span,
                          hint="write it like [0, -0.2, 1]", code="E302")
        xyz = self.numbers3(value, u.DIMENSIONLESS, "direction")
        norm = math.hypot(*xyz)
        if not norm >= MIN_DIRECTION_NORM:
            raise VfError("a direction cannot be zero", value.span, hint="give a non-zero vector, e.g. [0, 0, 1]",
                          code="E402")
        return [c / norm for c in xyz]

    def _composite(self, value: ast.Value, kind: str) -> ir.Value:
        fields = _COMPOSITES[kind]
        if not isinstance(value, ast.Call) or value.name.text != kind:
            raise self._wrong(value, kind)
        names = [name for name, _ in fields]
        bound = bind_arguments(value, names, names if kind != "pose" else (), f"{kind}(...)")
        out = {}
        for name, field_kind in fields:
            if name in bound:
                read = self.read(bound[name], field_kind)
                out[name] = read.xyz
            else:
                out[name] = [0.0, 0.0, 0.0]
        if kind == "line":
            return ir.LineValue(**out)
        if kind == "plane":
            return ir.PlaneValue(**out)
        return ir.PoseValue(**out)

    def _curve(self, value: ast.Value, degree: int | None) -> ir.CurveValue:
        points_value = value
        if isinstance(value, ast.Call):
            if value.name.text != "bspline":
                raise self._wrong(value, "curve")
            bound = bind_arguments(value, ["points", "degree"], (), "bspline(...)")
            if "points" not in bound:
                raise VfError("bspline(...) needs points = [[x, y, z], ...]", value.span, code="E401")
            points_value = bound["points"]
            if "degree" in bound:
                given = self.integer(bound["degree"], "degree")
                if degree is not None and given != degree:
                    raise VfError(f"the curve's degree is declared as {degree} but given here as {given}",
                                  bound["degree"].span, code="E401")
                degree = given
        if not isinstance(points_value, ast.Vector) or not all(isinstance(p, ast.Vector) for p in points_value.items):
            raise self._wrong(value, "curve")
        degree = 3 if degree is None else degree
        if degree > limits.CURVE_DEGREE:
            raise limits.exceeded(f"a degree-{degree} curve", limits.CURVE_DEGREE, value.span,
                                  hint="the paper uses degree 5; degree 1 is a polyline", code="E701")
        if len(points_value.items) > limits.CURVE_POINTS:
            raise limits.exceeded(f"a curve of {len(points_value.items):,} points", limits.CURVE_POINTS,
                                  points_value.span, code="E701")
        points = [self.numbers3(p if p.unit else p.model_copy(update={"unit": points_value.unit}), u.LENGTH, "point")
                  for p in points_value.items]
        if len(points) < degree + 1:
            raise VfError(f"a degree-{degree} b-spline needs at least {degree + 1} points, got {len(points)}",
                          points_value.span, hint="give more points, or lower the degree", code="E401")
        _check_sampling(points, points_value, self.units)
        return ir.CurveValue(degree=degree, points=points)

    def integer(self, value: ast.Value, what: str) -> int:
        if (not isinstance(value, ast.Quantity) or value.unit or not math.isfinite(value.number)
                or value.number != int(value.number) or value.number < 1):
            raise VfError(f"{what} must be a positive whole number", value.span, code="E402")
        return int(value.number)


def _check_sampling(points: list[list[float]], value: ast.Vector, units: u.DefaultUnits) -> None:
    """The compiler finds closest points among samples about SAMPLE_SPACING apart along the curve (at least
    MIN_SAMPLES): each span between two points must hold at least two samples, and the curve at most
    CURVE_SAMPLES. The polyline through the points stands for the curve's length here."""
    chords = [math.dist(a, b) for a, b in zip(points, points[1:])]
    length = math.fsum(chords)
    if not length <= (limits.CURVE_SAMPLES - 1) * SAMPLE_SPACING:      # also catches an infinite length
        raise limits.exceeded(f"this curve is too long ({units.show(length, u.LENGTH)} through its points) for "
                              f"closest-point samples {units.show(SAMPLE_SPACING, u.LENGTH)} apart",
                              limits.CURVE_SAMPLES, value.span, hint="the limit counts samples", code="E701")
    samples = max(MIN_SAMPLES, math.ceil(length / SAMPLE_SPACING) + 1)
    spacing = length / (samples - 1)
    for k, chord in enumerate(chords, start=1):
        where = value.items[k].span
        if chord == 0.0:
            raise VfError(f"curve points {k} and {k + 1} are the same point", where,
                          hint="remove the repeated point", code="E402")
        if chord < 2 * spacing:
            raise VfError(f"curve points {k} and {k + 1} are {units.show(chord, u.LENGTH)} apart, too close for "
                          f"the curve's closest-point samples ({units.show(spacing, u.LENGTH)} apart)", where,
                          hint=f"keep consecutive points at least {units.show(2 * spacing, u.LENGTH)} apart "
                               "(drop points, or space them out)", code="E402")


_FROM_MAPPING = ("point", "direction", "vector")
"""Kinds whose values no call writes: a call of that name is a scene's mapping, read as the param's kind."""


def _what(value: ast.Value) -> str:
    if isinstance(value, ast.Quantity):
        return f"the number {value.number:g}" + (f" {value.unit}" if value.unit else "")
    if isinstance(value, ast.Vector):
        return f"a list of {len(value.items)}"
    if isinstance(value, ast.Call) and not value.args and value.name.text in ("{mapping}", *_FROM_MAPPING):
        return "a mapping of " + ", ".join(k.name.text for k in value.kwargs)     # a scene's {x: .., y: ..}
    if isinstance(value, ast.Call):
        return f"{value.name.text}(...)"
    if isinstance(value, ast.NameRef):
        return f"the name '{value.name}'"
    if isinstance(value, ast.String):
        return f"the text {value.text!r}"
    if isinstance(value, (ast.BinOp, ast.Neg)):
        return "an expression"
    return "true/false"
