"""Derived geometry: expressions over points, vectors, directions, lines and planes -> IR arguments.

Kinds and units (a vector carries the dimension of its components; a direction is a unit vector of plain
numbers)::

    point + vector -> point      point - point -> vector (length)     point - vector -> point
    vector +- vector -> vector (same dimension)      -vector -> vector      -direction -> direction
    scalar * vector, vector * scalar -> vector (dimensions multiply)      scalar * scalar -> scalar
    normalize(vector) -> direction      cross(a, b) -> vector, dimension the product of a's and b's
    midpoint(a, b) -> point (of two points)
    line(a, b) -> the line through points a and b, or through a along b when b is a direction
    plane(point, normal) -> plane        (line/plane also take point = ..., direction/normal = ...)

A list of bare numbers takes its dimension from its use: a length next to a point or a length vector,
plain numbers when scaled, crossed or normalized, a direction as the second argument of line(...). A vector
of plain numbers stands where a direction is expected (normalized, as a literal direction is); any other
vector there is refused (normalize it). Adding two points, scaling a point, or vectors of different
dimensions are errors at the operator. An expression whose operands are all constants is folded to an
:class:`~vfdsl.ir.model.Const` here (a zero direction is an error at the expression); one with a run-time
param becomes an :class:`~vfdsl.ir.model.Derived`, checked here at the params' values.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import casadi as ca
import numpy as np

from vfdsl.compiler import derived
from vfdsl.compiler.context import ParamReader
from vfdsl.errors import VfError
from vfdsl.ir import model as ir
from vfdsl import units as u
from vfdsl.passes.calls import bind_arguments
from vfdsl.passes.shapes import LiteralReader, describe_kind
from vfdsl.primitives.spec import SCALAR_DIMENSIONS
from vfdsl.syntax import ast

KINDS = ("point", "vector", "direction", "line", "plane") + tuple(SCALAR_DIMENSIONS)
CALLS = ("cross", "normalize", "midpoint", "line", "plane")
_FIELDS = {"line": ("point", "direction"), "plane": ("point", "normal")}


def is_expression(value: ast.Value) -> bool:
    """Whether ``value`` is read here (operators, and calls of derived geometry) rather than as a literal."""
    return isinstance(value, (ast.BinOp, ast.Neg)) or (isinstance(value, ast.Call) and value.name.text in CALLS)


@dataclass(frozen=True)
class Typed:
    """A checked sub-expression: its kind, dimension (vectors, scalars) and IR argument."""

    kind: str                    # point, vector, direction, line, plane, scalar
    dim: u.Dim | None            # None for a list of bare numbers whose dimension is set by its use
    arg: ir.Arg | None           # None while dim is None
    node: ast.Value
    placeable: bool = False      # a vector that reads as a point where one is expected (see _as_point)

    def words(self) -> str:
        if self.kind == "vector" and self.dim is not None:
            return "a vector of plain numbers" if self.dim == u.DIMENSIONLESS else \
                f"a vector of {'lengths' if self.dim == u.LENGTH else u.si_formula(self.dim)}"
        if self.kind == "scalar":
            return u.describe(self.dim)
        return describe_kind(self.kind)


class Expressions:
    """Reads expressions in one scope: ``name`` resolves a name to its IR argument, ``kind_of`` gives an
    argument's kind, ``params`` are the task's params (their values check run-time expressions)."""

    def __init__(self, units: u.DefaultUnits, name: Callable[[ast.NameRef], ir.Arg],
                 kind_of: Callable[[ir.Arg], str], params: list[ir.ParamDecl]):
        self.reader = LiteralReader(units, lambda ref, kind: None)
        self.name = name
        self.kind_of = kind_of
        self.params = params
        self._bare: u.Dim | None = None      # while set, the dimension every list of bare numbers takes

    # ---------------------------------------------------------------------------------------- entry
    def evaluate(self, value: ast.Value, kind: str) -> ir.Arg:
        """``value`` as an argument of ``kind`` (one of KINDS)."""
        t = self.typed(value)
        if kind in SCALAR_DIMENSIONS:
            t = self._expect(t, "scalar", SCALAR_DIMENSIONS[kind], f"expected {describe_kind(kind)}")
            if not isinstance(t.arg, ir.Const):
                raise VfError("arithmetic on run-time scalars is not supported", value.span,
                              hint="compute the value in the scene, or use constants here", code="E403")
            return ir.Const(value=ir.ScalarValue(dimension=kind, value=t.arg.value.value))
        if kind == "direction":
            return self.direction(t, f"expected {describe_kind(kind)}").arg
        dim = u.LENGTH if kind in ("point", "vector") else None
        return self._expect(t, kind, dim, f"expected {describe_kind(kind)}").arg

    # ------------------------------------------------------------------------------------------ typing
    def typed(self, value: ast.Value) -> Typed:
        if isinstance(value, ast.NameRef):
            return self._name(value)
        if isinstance(value, ast.Quantity):
            dim = u.DIMENSIONLESS if value.unit is None else u.parse_unit(value.unit, value.span)[0]
            number = u.to_si(value.number, value.unit, dim, self.reader.units, value.span)
            return Typed("scalar", dim, _const_scalar(dim, number), value)
        if isinstance(value, ast.Vector):
            if value.unit is None and all(isinstance(i, ast.Quantity) and i.unit is None for i in value.items):
                return self._settle(Typed("vector", None, None, value, placeable=True), self._bare)
            unit = value.unit or next(i.unit for i in value.items if isinstance(i, ast.Quantity) and i.unit)
            return self._settle(Typed("vector", None, None, value, placeable=True), u.parse_unit(unit, value.span)[0])
        if isinstance(value, ast.Neg):
            return self._neg(value)
        if isinstance(value, ast.BinOp):
            left, right = self.typed(value.left), self.typed(value.right)
            return {"+": self._add, "-": self._sub, "*": self._mul}[value.op](value, left, right)
        if isinstance(value, ast.Call) and value.name.text in CALLS:
            return getattr(self, "_" + value.name.text)(value)
        what = f"{value.name.text}(...)" if isinstance(value, ast.Call) else "this value"
        raise VfError(f"{what} cannot be used in derived geometry", value.span,
                      hint="expressions combine points, vectors, directions and numbers", code="E403")

    def _name(self, ref: ast.NameRef) -> Typed:
        arg = self.name(ref)
        kind = self.kind_of(arg)
        if kind in ("point", "vector"):
            return Typed(kind, u.LENGTH, arg, ref)
        if kind == "direction":
            return Typed(kind, u.DIMENSIONLESS, arg, ref)
        if kind in ("line", "plane"):
            return Typed(kind, None, arg, ref)
        if kind in SCALAR_DIMENSIONS:
            return Typed("scalar", SCALAR_DIMENSIONS[kind], arg, ref)
        raise VfError(f"'{ref.name}' is {describe_kind(kind)}; it cannot be used in derived geometry", ref.span,
                      hint="expressions combine points, vectors, directions and numbers"
                           + ("; a frame moves with the robot" if kind == "frame" else ""), code="E203")

    def _settle(self, t: Typed, dim: u.Dim | None) -> Typed:
        """A list of bare numbers (or a sum or negation of such lists) read with dimension ``dim`` (a Typed
        with a dimension, or dim None, is returned as is)."""
        if t.dim is not None or t.kind != "vector" or dim is None:
            return t
        if not isinstance(t.node, ast.Vector):
            outer, self._bare = self._bare, dim
            try:
                return self.typed(t.node)
            finally:
                self._bare = outer
        xyz = self.reader.numbers3(t.node, dim, "vector")
        return Typed("vector", dim, ir.Const(value=ir.VectorValue(xyz=xyz)), t.node, t.placeable)

    def _vector(self, t: Typed, dim: u.Dim, what: str) -> Typed:
        """``t`` as a vector (a direction is one of plain numbers); ``dim`` settles a bare list."""
        if t.kind == "direction":
            return Typed("vector", u.DIMENSIONLESS, t.arg, t.node)
        if t.kind != "vector":
            hint = "subtract two points to get a vector: b - a" if t.kind == "point" else None
            raise VfError(f"{what} needs a vector here, got {t.words()}", t.node.span, hint=hint, code="E403")
        return self._settle(t, dim)

    def _as_point(self, t: Typed) -> Typed:
        """A constant vector of lengths, or one that a list literal places (literal + v, literal - v), read as
        the point it reaches from the world origin: the same numbers, labelled a point."""
        constant = t.arg is None or isinstance(t.arg, ir.Const)       # None: bare lists, not settled yet
        if t.kind != "vector" or t.dim not in (None, u.LENGTH) or not (t.placeable or constant):
            return t
        t = self._settle(t, u.LENGTH)
        arg = (ir.Const(value=ir.PointValue(xyz=t.arg.value.xyz)) if isinstance(t.arg, ir.Const)
               else t.arg.model_copy(update={"kind": "point"}))
        return Typed("point", u.LENGTH, arg, t.node)

    def _expect(self, t: Typed, kind: str, dim: u.Dim | None, what: str) -> Typed:
        if kind == "point":
            t = self._as_point(t)
        elif t.kind == "vector" and t.dim is None and kind == "vector":
            t = self._settle(t, dim)
        if t.kind == kind and (dim is None or t.dim == dim):
            return t
        hint = None
        if kind == t.kind == "scalar" and t.dim == u.DIMENSIONLESS:
            hint = "a bare number in an expression is a plain number; give it its unit, e.g. 5 mm + 3 mm"
        elif kind in ("point", "vector") and t.kind == "vector" and t.dim == u.DIMENSIONLESS:
            hint = "give the numbers a unit, [x, y, z] mm, or scale by a length: 10 mm * v"
        elif kind == "vector" and t.kind == "vector":
            hint = "normalize it and scale by a length: 10 mm * normalize(...)"
        elif kind == "point" and t.kind == "vector":
            hint = "add the vector to a point: p + v"
        raise VfError(f"{what}, got {t.words()}", t.node.span, hint=hint, code="E403")

    def direction(self, t: Typed, what: str) -> Typed:
        """``t`` where a direction is expected: a direction, or a vector of plain numbers (normalized)."""
        if t.kind == "direction":
            return t
        if t.kind == "vector" and t.dim in (None, u.DIMENSIONLESS):
            return self._node("normalize", "direction", [self._settle(t, u.DIMENSIONLESS)], t.node, u.DIMENSIONLESS)
        hint = None
        if t.kind == "vector":
            hint = "normalize it: normalize(...)"
        elif t.kind == "point":
            hint = "a point has no direction; did you mean normalize(b - a)?"
        raise VfError(f"{what}, got {t.words()}", t.node.span, hint=hint, code="E403")

    # -------------------------------------------------------------------------------------- operators
    def _add(self, node: ast.BinOp, a: Typed, b: Typed) -> Typed:
        if a.kind == "point" and b.kind == "point":
            raise VfError("adding two points has no meaning", node.span, hint="did you mean midpoint(a, b)?",
                          code="E403")
        if "point" in (a.kind, b.kind):
            point, vector = (a, b) if a.kind == "point" else (b, a)
            vector = self._length_vector(vector, node.op)
            return self._node("add", "point", [point, vector], node, u.LENGTH)
        return self._same_dims("add", node, a, b)

    def _sub(self, node: ast.BinOp, a: Typed, b: Typed) -> Typed:
        if a.kind == "point" and b.kind == "point":
            return self._node("sub", "vector", [a, b], node, u.LENGTH)
        if a.kind == "point":
            b = self._length_vector(b, node.op)
            return self._node("sub", "point", [a, b], node, u.LENGTH)
        if b.kind == "point":
            raise VfError("subtracting a point from a vector has no meaning", node.span,
                          hint="write point - vector, or point - point for the vector between them", code="E403")
        return self._same_dims("sub", node, a, b)

    def _length_vector(self, t: Typed, op: str) -> Typed:
        """The vector a point moves by (``op`` + or -): lengths."""
        t = self._vector(t, u.LENGTH, f"'{op}'")
        if t.dim != u.LENGTH:
            raise VfError(f"a point moves by a vector of lengths, got {t.words()}", t.node.span,
                          hint="scale it by a length: 10 mm * v" if t.dim == u.DIMENSIONLESS else None, code="E403")
        return t

    def _same_dims(self, op: str, node: ast.BinOp, a: Typed, b: Typed) -> Typed:
        if a.kind == b.kind == "vector" and a.dim is None and b.dim is None:
            return Typed("vector", None, None, node, placeable=True)     # bare lists: settled by their use
        a = self._vector(a, b.dim if b.kind == "vector" and b.dim is not None else u.DIMENSIONLESS,
                         f"'{node.op}'") if a.kind != "scalar" else a
        b = self._vector(b, a.dim if a.kind == "vector" else u.DIMENSIONLESS, f"'{node.op}'") \
            if b.kind != "scalar" else b
        if a.kind == "scalar" and b.kind == "scalar" and a.dim == b.dim:
            return self._scalar(node, a, b, np.add if op == "add" else np.subtract)
        if a.kind != b.kind or a.dim != b.dim:
            raise VfError(f"cannot {'add' if op == 'add' else 'subtract'} {b.words()} "
                          f"{'to' if op == 'add' else 'from'} {a.words()}", node.span, code="E403")
        placeable = a.dim == u.LENGTH and (a.placeable or (op == "add" and b.placeable))
        return replace(self._node(op, "vector", [a, b], node, a.dim), placeable=placeable)

    def _neg(self, node: ast.Neg) -> Typed:
        t = self.typed(node.operand)
        if t.kind == "scalar":
            return self._scalar(node, t, None, np.negative)
        if t.kind == "point":
            raise VfError("negating a point has no meaning", node.span, hint="negate a vector: -(b - a)", code="E403")
        if t.kind == "direction":
            return self._node("neg", "direction", [t], node, u.DIMENSIONLESS)
        if t.kind == "vector" and t.dim is None:
            return Typed("vector", None, None, node)                   # a bare list: settled by its use
        t = self._vector(t, u.DIMENSIONLESS, "'-'")
        return self._node("neg", "vector", [t], node, t.dim)

    def _mul(self, node: ast.BinOp, a: Typed, b: Typed) -> Typed:
        if a.kind == "scalar" and b.kind == "scalar":
            return self._scalar(node, a, b, np.multiply)
        if "scalar" not in (a.kind, b.kind):
            raise VfError(f"'*' multiplies a number and a vector, got {a.words()} and {b.words()}", node.span,
                          hint="for the cross product write cross(a, b)", code="E403")
        scalar, vector = (a, b) if a.kind == "scalar" else (b, a)
        if vector.kind == "point":
            raise VfError("scaling a point has no meaning", vector.node.span,
                          hint="scale a vector, e.g. 2 * (b - a)", code="E403")
        vector = self._vector(vector, u.DIMENSIONLESS, "'*'")
        return self._node("scale", "vector", [scalar, vector], node, _times(scalar.dim, vector.dim))

    # ------------------------------------------------------------------------------------------ calls
    def _args(self, call: ast.Call, count: int) -> list[Typed]:
        bound = bind_arguments(call, ["a", "b"][:count], ["a", "b"][:count], f"{call.name.text}(...)")
        return [self.typed(bound[n]) for n in ["a", "b"][:count]]

    def _cross(self, call: ast.Call) -> Typed:
        a, b = (self._vector(t, u.DIMENSIONLESS, "cross(...)") for t in self._args(call, 2))
        return self._node("cross", "vector", [a, b], call, _times(a.dim, b.dim))

    def _normalize(self, call: ast.Call) -> Typed:
        (t,) = self._args(call, 1)
        if t.kind == "point":
            raise VfError("normalize(...) needs a vector; a point has no direction", t.node.span,
                          hint="did you mean normalize(b - a)?", code="E403")
        t = self._vector(t, u.DIMENSIONLESS, "normalize(...)")
        return self._node("normalize", "direction", [t], call, u.DIMENSIONLESS)

    def _midpoint(self, call: ast.Call) -> Typed:
        a, b = (self._expect(t, "point", u.LENGTH, "midpoint(a, b) needs two points") for t in self._args(call, 2))
        return self._node("midpoint", "point", [a, b], call, u.LENGTH)

    def _line(self, call: ast.Call) -> Typed:
        return self._composite(call, "line")

    def _plane(self, call: ast.Call) -> Typed:
        return self._composite(call, "plane")

    def _composite(self, call: ast.Call, kind: str) -> Typed:
        """line(a, b) through two points, or line/plane(point, direction/normal) (positional or named)."""
        names = _FIELDS[kind]
        bound = bind_arguments(call, list(names), names, f"{kind}(...)")
        point = self._expect(self.typed(bound["point"]), "point", u.LENGTH, f"{kind}(...) needs a point first")
        second = self.typed(bound[names[1]])
        if kind == "line" and second.dim == u.LENGTH:
            second = self._as_point(second)
        if kind == "line" and second.kind == "point" and not any(k.name.text == "direction" for k in call.kwargs):
            return self._node("line2", "line", [point, second], call, None)
        if kind == "line" and second.kind == "vector" and second.dim == u.LENGTH:
            raise VfError("line(a, b) needs two points, or a point and a direction; got a vector of lengths",
                          second.node.span, hint="write line(a, a + v) or line(a, normalize(v))", code="E403")
        direction = self.direction(second, f"the {names[1]} of {kind}(...) must be a direction")
        return self._node(kind, kind, [point, direction], call, None)

    # -------------------------------------------------------------------------------------- IR nodes
    def _node(self, op: str, kind: str, operands: list[Typed], node: ast.Value, dim: u.Dim | None) -> Typed:
        """The Derived node of ``op``, folded to a Const when every operand is constant."""
        result = ir.Derived(op=op, kind=kind, operands=[t.arg for t in operands], span=node.span)
        if any(reads_capture(t.arg) for t in operands):        # its value is known when the phase is entered
            return Typed(kind, dim, result, node)
        constant = all(isinstance(t.arg, ir.Const) for t in operands)
        read = ParamReader([]).read if constant else self._defaults().read
        try:                                # a zero direction, or a value that overflows
            derived.check(result, read, "" if constant else "with the params' values, ")
        except VfError as error:
            raise error.with_code("E402") from None
        if constant:
            value = derived.evaluate(result, read)
            return Typed(kind, dim, ir.Const(value=derived.to_value(kind, value)), node)
        return Typed(kind, dim, result, node)

    def _defaults(self) -> ParamReader:
        """The params at their values (numbers)."""
        return ParamReader(self.params, ca.DM(ParamReader(self.params).layout.defaults))

    def _scalar(self, node: ast.Value, a: Typed, b: Typed | None, op) -> Typed:
        if not all(isinstance(t.arg, ir.Const) for t in (a, b) if t is not None):
            raise VfError("arithmetic on run-time scalars is not supported", node.span,
                          hint="compute the value in the scene, or use constants here", code="E403")
        numbers = [t.arg.value.value for t in (a, b) if t is not None]
        dim = _times(a.dim, b.dim) if op is np.multiply else a.dim
        with np.errstate(over="ignore"):
            value = float(op(*numbers))
        if not np.isfinite(value):
            raise VfError("this value is too large (SI numbers overflow)", node.span, code="E304")
        return Typed("scalar", dim, _const_scalar(dim, value), node)


def _times(a: u.Dim, b: u.Dim) -> u.Dim:
    return tuple(x + y for x, y in zip(a, b))


def dimension_name(dim: u.Dim) -> str:
    """A dimension's scalar kind ('length', 'force', ...), else its SI formula."""
    return next((k for k, d in SCALAR_DIMENSIONS.items() if d == dim), u.si_formula(dim))


def _const_scalar(dim: u.Dim, value: float) -> ir.Const:
    return ir.Const(value=ir.ScalarValue(dimension=dimension_name(dim), value=value))


def reads_capture(arg: ir.Arg) -> bool:
    """Whether ``arg`` reads a value captured on entry to a phase (known only when the phase runs)."""
    return isinstance(arg, ir.CaptureRef) or (isinstance(arg, ir.Derived) and any(map(reads_capture, arg.operands)))
