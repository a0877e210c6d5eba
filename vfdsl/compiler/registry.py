"""The lowerings the compiler calls by name: one per constraint primitive and one per objective term.

:mod:`vfdsl.primitives` and :mod:`vfdsl.objectives` build on the compiler (its rows, geometry and context), so
the compiler does not import them: each of them registers its modules here when it is imported (importing
``vfdsl`` imports both), and the compiler looks a statement's lowering up by the statement's name.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from vfdsl.compiler.context import Context
from vfdsl.compiler.rows import Rows, Term
from vfdsl.ir import model as ir


class Argument(Protocol):
    """What the compiler reads of an argument's signature: its name and the allowed range of a scalar (or None)."""

    name: str
    range: object


class Signature(Protocol):
    """What the compiler reads of a primitive's or term's signature (:mod:`vfdsl.primitives.spec`)."""

    name: str
    args: Sequence[Argument]


class ConstraintSignature(Signature, Protocol):
    """A primitive's signature; ``rate``: its rows bound a motion per tick (a speed), not a position."""

    rate: bool


@dataclass(frozen=True)
class ConstraintLowering:
    """A primitive: its signature and its rows."""

    spec: ConstraintSignature
    lower: Callable[[ir.Constraint, Context], Rows]


@dataclass(frozen=True)
class ObjectiveLowering:
    """An objective term: its signature and its terms."""

    spec: Signature
    lower: Callable[[ir.Objective, Context], Sequence[Term]]


CONSTRAINTS: dict[str, ConstraintLowering] = {}
OBJECTIVES: dict[str, ObjectiveLowering] = {}


def register_constraint(spec: ConstraintSignature, lower: Callable[[ir.Constraint, Context], Rows]) -> None:
    """Make the primitive ``spec.name`` lowerable."""
    CONSTRAINTS[spec.name] = ConstraintLowering(spec, lower)


def register_objective(spec: Signature, lower: Callable[[ir.Objective, Context], Sequence[Term]]) -> None:
    """Make the objective term ``spec.name`` lowerable."""
    OBJECTIVES[spec.name] = ObjectiveLowering(spec, lower)


def constraint(name: str) -> ConstraintLowering:
    """The lowering of primitive ``name``; LookupError when no module registered it."""
    if name not in CONSTRAINTS:
        raise LookupError(f"no lowering is registered for the primitive '{name}' (vfdsl.primitives registers them)")
    return CONSTRAINTS[name]


def objective(name: str) -> ObjectiveLowering:
    """The lowering of objective term ``name``; LookupError when no module registered it."""
    if name not in OBJECTIVES:
        raise LookupError(f"no lowering is registered for the objective term '{name}' (vfdsl.objectives registers "
                          "them)")
    return OBJECTIVES[name]
