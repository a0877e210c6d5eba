"""Derived values (:class:`~vfdsl.ir.model.Derived`): the math of each op, on CasADi numbers (DM) or symbols (SX).

Points, vectors and directions are 3-vectors, scalars 1 x 1; a line is (point, unit direction), a plane
(point, unit normal)::

    add: a + b     sub: a - b     neg: -a     scale: s a     cross: a x b     midpoint: (a + b) / 2
    normalize: a / |a|     line2 (through a and b): (a, (b - a) / |b - a|)     line, plane: (a, d / |d|)

A vector shorter than ``MIN_NORM`` (SI units of its dimension: 1 nm for a length) has no direction.
:func:`add_checks` writes these checks into a task's column of margins (:mod:`vfdsl.compiler.admissible`):
a VfError at the expression at load time with the params' values, and each tick a caller passes params, in
Python and in the generated C alike; in the step itself the division is guarded (no NaN).
"""

from __future__ import annotations

from functools import partial
from typing import Callable

import casadi as ca
import numpy as np

from vfdsl.compiler.geometry import normalize
from vfdsl.compiler.margins import Check, Margins
from vfdsl.ir import model as ir

MIN_NORM = 1e-9
_LARGEST = float(np.finfo(float).max)

Read = Callable[[ir.Arg], object]                 # a non-derived argument -> its DM/SX value in the world
Unit = Callable[[object, ir.Derived], object]     # (vector, the node normalizing it) -> the unit vector


def evaluate(arg: ir.Arg, read: Read, unit: Unit = lambda v, node: normalize(v)):
    """The value of ``arg``: ``read(arg)`` for a leaf, else its op applied to its operands' values."""
    if not isinstance(arg, ir.Derived):
        return read(arg)
    x = [evaluate(operand, read, unit) for operand in arg.operands]
    op = arg.op
    if op == "add":
        return x[0] + x[1]
    if op == "sub":
        return x[0] - x[1]
    if op == "neg":
        return -x[0]
    if op == "scale":
        return x[0] * x[1]
    if op == "cross":
        return ca.cross(x[0], x[1])
    if op == "midpoint":
        return (x[0] + x[1]) / 2
    if op == "normalize":
        return unit(x[0], arg)
    if op == "line2":
        return x[0], unit(x[1] - x[0], arg)
    return x[0], unit(x[1], arg)                  # line (point, direction), plane (point, normal)


def add_checks(margins: Margins, arg: ir.Derived, read: Read, notes: tuple[str, ...] = ()) -> None:
    """Append the checks of ``arg`` to ``margins`` (:mod:`vfdsl.compiler.margins`), in evaluation order: every
    vector it normalizes at least ``MIN_NORM`` long and finite, then its value finite. ``notes`` go with every
    error (the use site of the fixture that wrote ``arg``)."""
    def unit(v, node: ir.Derived):
        margins.add(ca.norm_2(v) - MIN_NORM,
                    Check(partial(_zero_message, node), _ZERO_MEANING.get(node.op, _ZERO_MEANING["direction"]),
                          node.span, ZERO_HINT, notes=notes))
        return normalize(v)
    value = evaluate(arg, read, unit)
    numbers = ca.vertcat(*value) if isinstance(value, tuple) else value
    margins.add(_LARGEST - ca.mmax(ca.fabs(numbers)),          # not 0 * |v|: CasADi folds that to 0
                Check(lambda margin, p: "this value is too large (SI numbers overflow)",
                      "a derived value must be finite", arg.span, notes=notes))


def check(arg: ir.Derived, read: Read, when: str = "") -> None:
    """VfError (prefixed by ``when``) at the first check of ``arg`` that fails, with numbers (``read`` gives DM)."""
    margins = Margins()
    add_checks(margins, arg, read)
    margins.verify(ca.DM(margins.symbolic()), when=when)


_ZERO_MEANING = {"line2": "the two points of a derived line must be distinct",
                 "normalize": "a normalized derived vector must not be zero",
                 "direction": "a derived direction must not be zero"}
ZERO_HINT = ("a derived direction needs two distinct points, or a non-zero, non-parallel vector "
              f"(at least {MIN_NORM:g} SI)")


def _zero_message(node: ir.Derived, margin: float, p) -> str:
    """What is wrong when the length ``node`` divides by is ``margin + MIN_NORM``."""
    if not np.isfinite(margin):
        return "the vector this normalizes is too large (SI numbers overflow)"
    what = {"line2": "the two points of this line coincide",
            "normalize": "this vector is zero"}.get(node.op, "this direction is zero")
    return f"{what} (length {margin + MIN_NORM:.3g} SI): it has no direction"


def leaves(arg: ir.Arg):
    """The non-derived arguments ``arg`` is computed from (``arg`` itself when it is not derived)."""
    if isinstance(arg, ir.Derived):
        for operand in arg.operands:
            yield from leaves(operand)
    else:
        yield arg


def reads_capture(arg: ir.Arg) -> bool:
    """``arg`` is computed from a captured value (it has none before its phase is entered)."""
    return any(isinstance(leaf, ir.CaptureRef) for leaf in leaves(arg))


def to_value(kind: str, value) -> ir.Value:
    """A numeric result of :func:`evaluate` (DM) as the IR value of ``kind``."""
    if kind in ("line", "plane"):
        point, unit = (np.array(ca.DM(x)).ravel().tolist() for x in value)
        return ir.LineValue(point=point, direction=unit) if kind == "line" else ir.PlaneValue(point=point, normal=unit)
    xyz = np.array(ca.DM(value)).ravel().tolist()
    return {"point": ir.PointValue, "vector": ir.VectorValue, "direction": ir.DirectionValue}[kind](xyz=xyz)
