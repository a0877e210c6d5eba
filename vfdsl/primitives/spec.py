"""Signatures of constraint primitives and objective terms: what the front end checks a call against.

Each primitive module declares one ``SPEC``; the elaborator checks a ``require``/``minimize`` call against it
generically (argument names, kinds, units, defaults, tolerance and resolution), so adding a primitive
never touches the front end.

Argument kinds: geometric values (point, vector, direction, line, plane, pose, curve, mesh), scalars with a
dimension (length, angle, speed, angular_speed, number), ``flag`` (true/false), ``frame`` and ``input``
(names of declared task frames and inputs), and ``gain``/``angular_gain``, whose dimension follows the
type of the call's ``input`` argument (see :func:`gain_dimension`).

Every scalar argument states its allowed values once, as a :class:`Range` in SI units: the front end checks
literals and param values against it at load time, the runtime checks run-time param values against the
same range, and the docs tables are generated from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, Literal

from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl import limits
from vfdsl import units as u

if TYPE_CHECKING:
    import casadi as ca

    from vfdsl.compiler.context import Context

GEOMETRIC_KINDS = ("point", "vector", "direction", "line", "plane", "pose", "curve", "mesh")
SCALAR_DIMENSIONS: dict[str, u.Dim] = {
    "length": u.LENGTH, "angle": u.ANGLE, "speed": u.SPEED, "angular_speed": u.ANGULAR_SPEED,
    "number": u.DIMENSIONLESS, "time": u.TIME, "force": u.FORCE,
    "stiffness": u.STIFFNESS, "force_damping": u.FORCE_DAMPING, "force_rate": u.FORCE_RATE,
}
VALUE_KINDS = GEOMETRIC_KINDS + tuple(SCALAR_DIMENSIONS) + ("flag",)
NAME_KINDS = ("frame", "input")
ARG_KINDS = VALUE_KINDS + NAME_KINDS + ("gain", "angular_gain", "choice")

REQUIRED = object()


@dataclass(frozen=True)
class Range:
    """Allowed values of a scalar argument, in SI units; None = unbounded on that side.

    ``unit`` (a name from :data:`vfdsl.units.UNITS`, e.g. "deg") only changes how the bounds are
    written in messages and docs. Non-finite values are never allowed.
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = False        # True: low itself is not allowed (value > low)
    high_open: bool = False
    unit: str | None = None

    def violation(self, value: float) -> str | None:
        """None when ``value`` is allowed, else a short phrase such as 'must be > 0' or 'must be in (0, 90) deg'."""
        if not math.isfinite(value):
            return "must be finite"
        too_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
        too_high = self.high is not None and (value >= self.high if self.high_open else value > self.high)
        if not (too_low or too_high):
            return None
        return f"must be in {self.describe()}" if self.low is not None and self.high is not None \
            else f"must be {self.describe()}"

    def describe(self) -> str:
        """The allowed values in words, for docs and messages: '> 0', '(0, 1]', '(0, 90) deg', 'any'."""
        scale = u.UNITS[self.unit][1] if self.unit else 1.0
        low = None if self.low is None else f"{self.low / scale:.6g}"
        high = None if self.high is None else f"{self.high / scale:.6g}"
        if low is not None and high is not None:
            text = f"{'(' if self.low_open else '['}{low}, {high}{')' if self.high_open else ']'}"
        elif low is not None:
            text = f"{'>' if self.low_open else '>='} {low}"
        elif high is not None:
            text = f"{'<' if self.high_open else '<='} {high}"
        else:
            return "any"
        return f"{text} {self.unit}" if self.unit else text


POSITIVE = Range(low=0.0, low_open=True)
SIZE = Range(low=0.0, low_open=True, high=limits.ROW_VALUE)
"""A positive length, speed or angular speed, at most :data:`vfdsl.limits.ROW_VALUE` (SI): a larger one is no robot's
(a unit slip), overflows the simulator's arithmetic, and its rows are beyond what ``vfdsl check`` analyses."""
GAIN = Range(low=1 / limits.GAIN, high=limits.GAIN)
"""A ``track`` gain (SI): velocity = gain * input, from 1 um/s to 1000 km/s per N (or rad/s per N m, or a scale)."""

ResolutionShape = Literal["sphere", "polygon"] | None


@dataclass(frozen=True)
class ArgSpec:
    name: str
    kind: str
    doc: str
    default: object = REQUIRED       # an ir.Value, or REQUIRED; "subject" means the constraint's own frame
    range: Range | None = None       # allowed values of a scalar argument (SI); None: any finite value
    choices: tuple[str, ...] = ()    # the words a ``choice`` argument may be (its default: an ir.ChoiceValue)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class ConstraintSpec:
    """A ``require`` primitive. ``subject``: applied to a task frame (``require tip stays_at(p)``).

    Besides its signature it states what the tools around the compiler read of it, so that its module is
    its one home (``tests/test_registry.py`` names the tool that misses a primitive):

    - ``metric``: the dimension of its error in ``simulate`` ("length", "angle", "speed", "angular_speed"; a
      joint primitive: that of its prismatic joints, the revolute ones' is the angular counterpart);
    - ``row_unit``: without a tolerance, the unit of what its rows bound ("m", "rad"; "" when not stated);
      with one, the tolerance's unit;
    - ``stated_by``: (kind, argument) of the size its rows bound when an argument states it, not the tolerance;
    - ``exact_rows``: how ``check``'s bounds table names its rows when they are exact (no polytope);
    - ``true_angle``: for rows that linearize a direction with a cross product (blind to an opposite axis),
      the true angle error as a CasADi expression of (constraint, context); ``check`` measures it at the start;
    - ``reference_point``: the argument naming the point its frame is held to or by, and
      ``error_is_distance``: its error at rest is the distance to that point itself;
    - ``drawn_around_frame``: the viewer draws it around the frame's position (a plane's square, a line's
      stretch, a cone's apex), so it is redrawn as the frame moves;
    - ``kept_angle``: with ``true_angle``, the angle its tool axis keeps from its direction or axis, by which
      ``check`` names the likely cause of an error far beyond the tolerance: 0.0 (along it: beyond 150 deg the
      direction is the opposite one), the argument stating it (a cone's half-angle gamma: nearer pi - gamma
      the axis is reversed, at gamma read in deg a unit slip), or None;
    - ``angle_rows``: with ``true_angle``, what its rows measure of the angle, for ``check``'s messages:
      "sin" (a cross product) or "cos" (one row, cos gamma - cos of the angle, unitless);
    - ``admitted``: for rows that bound another measure of the error than the error itself, the largest true error
      they admit when they hold within e (the polytope's circumradius times the stated size), a function of
      (constraint, task, e); None: e itself.
    """

    name: str
    summary: str
    subject: bool
    args: tuple[ArgSpec, ...] = ()
    tolerance: str | None = None                 # scalar kind of `within`, or None if it takes none
    default_tolerance: float | None = None       # SI
    resolution: ResolutionShape | Callable[[dict], ResolutionShape] = None
    default_resolution: dict = field(default_factory=lambda: {"sphere": [4, 4], "polygon": [8]})
    source: str = ""                             # where the math comes from (paper equation, lecture slide)
    rate: bool = False                           # rows bound a motion per tick (a speed), not a position
    metric: str | None = None
    row_unit: str | None = None
    stated_by: tuple[str, str] | None = None
    exact_rows: str = "exact"
    true_angle: Callable[[ir.Constraint, Context], ca.SX] | None = None
    reference_point: str | None = None
    error_is_distance: bool = False
    drawn_around_frame: bool = False
    kept_angle: float | str | None = None
    angle_rows: Literal["sin", "cos"] = "sin"
    admitted: Callable[[ir.Constraint, ir.Task, float], float] | None = None

    @property
    def reads_mesh(self) -> bool:
        """Whether it keeps the frame clear of a triangle mesh (a ``mesh`` argument)."""
        return any(a.kind == "mesh" for a in self.args)

    def resolution_shape(self, args: dict[str, ir.Arg]) -> ResolutionShape:
        return self.resolution(args) if callable(self.resolution) else self.resolution


TASK_LEVEL = 1
"""Default priority of terms that state what the user wants (track, distance, direction_change)."""
REDUNDANCY_LEVEL = 2
"""Default priority of redundancy terms (damping, centering): they act in the optimal set of the task terms."""


@dataclass(frozen=True)
class ObjectiveSpec:
    """A ``minimize`` term: weight * || E dq/dt - f ||^2, a rate error (m/s, rad/s, 1/s); ``priority``: the
    default level it is solved at."""

    name: str
    summary: str
    args: tuple[ArgSpec, ...] = ()
    source: str = ""
    priority: int = TASK_LEVEL


def gain_dimension(input_type: str, kind: str) -> u.Dim | None:
    """Dimension of a ``gain`` (linear part) or ``angular_gain`` for an input of ``input_type``;
    None when that input has no such part (a force has no angular gain)."""
    return INPUT_TYPES[input_type].gain_dimension(angular=kind == "angular_gain")


def choice(args: dict[str, ir.Arg], name: str) -> str:
    """The word a ``choice`` argument holds (its default when not given)."""
    return args[name].value.value


def flag(args: dict[str, ir.Arg], name: str) -> bool:
    arg = args.get(name)
    return bool(isinstance(arg, ir.Const) and isinstance(arg.value, ir.FlagValue) and arg.value.value)
