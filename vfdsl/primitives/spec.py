"""Signatures of constraint primitives and objective terms: what the front end checks a call against.

Each primitive module declares one ``SPEC``; the elaborator checks a ``require``/``minimize`` call against it
generically (argument names, kinds, units, defaults, tolerance and resolution), so adding a primitive
never touches the front end.

Argument kinds: geometric values (point, vector, direction, line, plane, pose, curve), scalars with a
dimension (length, angle, speed, angular_speed, number), ``flag`` (true/false), ``frame`` and ``input``
(names of declared task frames and inputs), and ``gain``/``angular_gain``, whose dimension follows the
type of the call's ``input`` argument (see :func:`gain_dimension`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Literal

from vfdsl.ir import model as ir
from vfdsl.passes import units as u

GEOMETRIC_KINDS = ("point", "vector", "direction", "line", "plane", "pose", "curve")
SCALAR_DIMENSIONS: dict[str, u.Dim] = {
    "length": u.LENGTH, "angle": u.ANGLE, "speed": u.SPEED, "angular_speed": u.ANGULAR_SPEED,
    "number": u.DIMENSIONLESS, "time": u.TIME, "force": u.FORCE,
}
VALUE_KINDS = GEOMETRIC_KINDS + tuple(SCALAR_DIMENSIONS) + ("flag",)
NAME_KINDS = ("frame", "input")
ARG_KINDS = VALUE_KINDS + NAME_KINDS + ("gain", "angular_gain")

REQUIRED = object()

ResolutionShape = Literal["sphere", "polygon"] | None


@dataclass(frozen=True)
class ArgSpec:
    name: str
    kind: str
    doc: str
    default: object = REQUIRED       # an ir.Value, or REQUIRED; "subject" means the constraint's own frame

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class ConstraintSpec:
    """A ``require`` primitive. ``subject``: applied to a task frame (``require tip stays_at(p)``)."""

    name: str
    summary: str
    subject: bool
    args: tuple[ArgSpec, ...] = ()
    tolerance: str | None = None                 # scalar kind of `within`, or None if it takes none
    default_tolerance: float | None = None       # SI
    resolution: ResolutionShape | Callable[[dict], ResolutionShape] = None
    default_resolution: dict = field(default_factory=lambda: {"sphere": [4, 4], "polygon": [8]})
    source: str = ""                             # where the math comes from (paper equation, lecture slide)

    def resolution_shape(self, args: dict[str, ir.Arg]) -> ResolutionShape:
        return self.resolution(args) if callable(self.resolution) else self.resolution


@dataclass(frozen=True)
class ObjectiveSpec:
    """A ``minimize`` term: weight * || E dq - f ||^2."""

    name: str
    summary: str
    args: tuple[ArgSpec, ...] = ()
    source: str = ""


# Input type -> dimensions of (gain, angular_gain): the admittance law maps the input to a frame velocity.
_GAIN_DIMENSIONS: dict[str, tuple[u.Dim | None, u.Dim | None]] = {
    "force": ((1, 0, -1, -1), None),            # m/s per N
    "torque": (None, (-1, 1, -1, -1)),          # rad/s per N m
    "wrench": ((1, 0, -1, -1), (-1, 1, -1, -1)),
    "twist": (u.DIMENSIONLESS, u.DIMENSIONLESS),
}


def gain_dimension(input_type: str, kind: str) -> u.Dim | None:
    """Dimension of a ``gain`` (linear part) or ``angular_gain`` for an input of ``input_type``;
    None when that input has no such part (a force has no angular gain)."""
    linear, angular = _GAIN_DIMENSIONS[input_type]
    return linear if kind == "gain" else angular


def flag(args: dict[str, ir.Arg], name: str) -> bool:
    arg = args.get(name)
    return bool(isinstance(arg, ir.Const) and isinstance(arg.value, ir.FlagValue) and arg.value.value)
