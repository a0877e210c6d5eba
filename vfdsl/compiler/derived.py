"""Derived values (:class:`~vfdsl.ir.model.Derived`): the math of each op, on CasADi numbers (DM) or symbols (SX).

Points, vectors and directions are 3-vectors, scalars 1 x 1; a line is (point, unit direction), a plane
(point, unit normal)::

    add: a + b     sub: a - b     neg: -a     scale: s a     cross: a x b     midpoint: (a + b) / 2
    normalize: a / |a|     line2 (through a and b): (a, (b - a) / |b - a|)     line, plane: (a, d / |d|)

A vector shorter than ``MIN_NORM`` (SI units of its dimension: 1 nm for a length) has no direction.
:func:`check` refuses it, and any derived value that overflows, with a VfError at the expression (at load
time with the params' values, and each tick a caller passes params); in the generated code the division is
guarded (no NaN).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from vfdsl.compiler.geometry import normalize
from vfdsl.errors import VfError
from vfdsl.ir import model as ir

MIN_NORM = 1e-9

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


@dataclass(frozen=True)
class Checks:
    """What the entries of a check column are: the length each normalization divides by, then the value
    of each derived argument (a line or plane as point, then unit vector)."""

    lengths: list[ir.Derived]
    values: list[tuple[ir.Derived, int]]              # (argument, size of its value)


def checks(args: list[ir.Derived], read: Read) -> tuple[Checks, object]:
    """The check column of ``args`` (DM numbers, or SX to build a function of p) and what its entries are."""
    lengths, values, column = [], [], []

    def record(v, node):
        lengths.append(node)
        column.append(ca.norm_2(v))
        return normalize(v)
    for arg in args:
        value = evaluate(arg, read, record)
        value = ca.vertcat(*value) if isinstance(value, tuple) else value
        values.append((arg, value.numel()))
        column.append(value)
    return Checks(lengths, values), ca.vertcat(*column)


def verify(what: Checks, column, when: str = "") -> None:
    """VfError at the first normalization whose vector is too short (or not finite), or at the first derived
    argument whose value is not finite; ``when`` prefixes the message."""
    numbers = np.asarray(column, dtype=float).ravel()
    for node, norm in zip(what.lengths, numbers):
        zero_error(node, float(norm), when)
    at = len(what.lengths)
    for node, size in what.values:
        if not np.all(np.isfinite(numbers[at:at + size])):
            raise VfError(f"{when}this value is too large (SI numbers overflow)", node.span.pos())
        at += size


def check(arg: ir.Derived, read: Read, when: str = "") -> None:
    """:func:`verify` of one argument, with numbers."""
    what, column = checks([arg], read)
    verify(what, ca.DM(column), when)


def zero_error(node: ir.Derived, norm: float, when: str = "") -> None:
    """Raise when ``norm`` (the length ``node`` divides by) is too short to give a direction, or not finite."""
    if MIN_NORM <= norm < np.inf:
        return
    if not norm < np.inf:
        raise VfError(f"{when}the vector this normalizes is too large (SI numbers overflow)", node.span.pos())
    what = {"line2": "the two points of this line coincide",
            "normalize": "this vector is zero"}.get(node.op, "this direction is zero")
    raise VfError(f"{when}{what} (length {norm:.3g} SI): it has no direction", node.span.pos(),
                  hint="a derived direction needs two distinct points, or a non-zero, non-parallel vector "
                       f"(at least {MIN_NORM:g} SI)")


def derived_args(task: ir.Task) -> list[ir.Derived]:
    """The derived arguments of the task's constraints and objectives (outermost nodes)."""
    return [arg for statement in [*task.constraints, *task.objectives] for arg in statement.args.values()
            if isinstance(arg, ir.Derived)]


def leaves(arg: ir.Arg):
    """The non-derived arguments ``arg`` is computed from (``arg`` itself when it is not derived)."""
    if isinstance(arg, ir.Derived):
        for operand in arg.operands:
            yield from leaves(operand)
    else:
        yield arg


def to_value(kind: str, value) -> ir.Value:
    """A numeric result of :func:`evaluate` (DM) as the IR value of ``kind``."""
    if kind in ("line", "plane"):
        point, unit = (np.array(ca.DM(x)).ravel().tolist() for x in value)
        return ir.LineValue(point=point, direction=unit) if kind == "line" else ir.PlaneValue(point=point, normal=unit)
    xyz = np.array(ca.DM(value)).ravel().tolist()
    return {"point": ir.PointValue, "vector": ir.VectorValue, "direction": ir.DirectionValue}[kind](xyz=xyz)
