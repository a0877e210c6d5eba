"""The checked IR: a task with every name resolved, every number in SI units (m, rad, s, N) and every
shape checked. This is exactly what the compiler sees, and what ``vfdsl show`` prints.

Each declaration, constraint and objective keeps the :class:`~vfdsl.errors.Span` it came from;
statements expanded from a fixture also keep ``via``, the chain of ``use`` sites that produced them.
The IR round-trips through JSON: ``Task.model_validate_json(task.model_dump_json()) == task``.
"""

from __future__ import annotations

import os
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_serializer

from vfdsl.errors import Span, VfError
from vfdsl.inputs import INPUT_TYPES

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# ------------------------------------------------------------------------------------------ values (SI)

class PointValue(_Model):
    kind: Literal["point"] = "point"
    xyz: Vec3


class VectorValue(_Model):
    """A displacement (metres), e.g. the shift between a curve and its copy along the tool."""

    kind: Literal["vector"] = "vector"
    xyz: Vec3


class DirectionValue(_Model):
    """A unit vector (normalized by the compiler)."""

    kind: Literal["direction"] = "direction"
    xyz: Vec3


class LineValue(_Model):
    kind: Literal["line"] = "line"
    point: Vec3
    direction: Vec3                  # unit


class PlaneValue(_Model):
    kind: Literal["plane"] = "plane"
    point: Vec3
    normal: Vec3                     # unit, toward the free side


class PoseValue(_Model):
    """A rigid transform world <- local: p_world = R(rpy) p_local + translation (URDF's fixed-axis rpy)."""

    kind: Literal["pose"] = "pose"
    translation: Vec3
    rpy: Vec3


class CurveValue(_Model):
    """A b-spline of ``degree`` interpolating ``points`` (in order); ``runtime``: the points are run-time
    params (these are their defaults), interpolated with the chord-length parameters of these points."""

    kind: Literal["curve"] = "curve"
    degree: int
    points: list[Vec3]
    runtime: bool = False


class MeshValue(_Model):
    """A triangle mesh read from ``file`` (absolute path) at compile time, one file unit = ``unit`` metres;
    ``sha256`` of the file's bytes and the unit (a changed file is a changed task)."""

    kind: Literal["mesh"] = "mesh"
    file: str
    unit: float
    sha256: str


class ScalarValue(_Model):
    """A number with a named dimension ('length', 'angle', 'speed', 'number', ...), in SI."""

    kind: Literal["scalar"] = "scalar"
    dimension: str
    value: float


class FlagValue(_Model):
    kind: Literal["flag"] = "flag"
    value: bool


class ChoiceValue(_Model):
    """One of the words an argument of kind ``choice`` allows (e.g. teleop's rotation = relative)."""

    kind: Literal["choice"] = "choice"
    value: str


Value = Annotated[
    Union[PointValue, VectorValue, DirectionValue, LineValue, PlaneValue, PoseValue, CurveValue, MeshValue,
          ScalarValue, FlagValue, ChoiceValue],
    Field(discriminator="kind"),
]


# -------------------------------------------------------------------------------------------- arguments

class ParamRef(_Model):
    """A run-time parameter, read each tick (its value may change while the controller runs)."""

    ref: Literal["param"] = "param"
    name: str


class FrameRef(_Model):
    ref: Literal["frame"] = "frame"
    name: str


class InputRef(_Model):
    ref: Literal["input"] = "input"
    name: str


class Const(_Model):
    """A value fixed at compile time."""

    ref: Literal["const"] = "const"
    value: Value


class Derived(_Model):
    """A value computed from other arguments (derived geometry), evaluated each tick because an operand is a
    run-time param (all-constant expressions are folded to :class:`Const` at load time). Vectors inside may
    have any dimension (checked at load time); the math of each op is in :mod:`vfdsl.compiler.derived`."""

    ref: Literal["derived"] = "derived"
    op: Literal["add", "sub", "neg", "scale", "cross", "normalize", "midpoint", "line", "line2", "plane"]
    kind: Literal["point", "vector", "direction", "line", "plane"]
    operands: list["Arg"]
    span: Span                       # where the expression is written (run-time errors point here)


class CaptureRef(_Model):
    """A value captured on entry to a phase (:class:`Capture`), read like a run-time param; before any phase that
    captures it has run, it holds its value at the initial phase's entry."""

    ref: Literal["capture"] = "capture"
    name: str


Arg = Annotated[Union[ParamRef, FrameRef, InputRef, Const, Derived, CaptureRef], Field(discriminator="ref")]
Derived.model_rebuild()


# --------------------------------------------------------------------------------------------- declarations

class RobotDecl(_Model):
    name: str
    urdf: str                        # a shipped robot's name ("shr7"), or the absolute path of a URDF file
    span: Span


class FrameDecl(_Model):
    """A task frame: a robot link, an offset pose in the link frame, and the local tool axis (unit)."""

    name: str
    robot: str
    link: str
    offset: Vec3                     # metres, in the link frame
    rpy: Vec3                        # radians, fixed-axis roll-pitch-yaw of the frame in the link frame
    tool_axis: Vec3                  # unit vector in the frame's own coordinates
    span: Span
    base: str | None = None          # the frame it was built on (`frame b = a offset ...`), already composed in


class InputDecl(_Model):
    """A signal read every tick: force (N), torque (N m), wrench [f; tau] or twist [v; w] (SI); its type is one
    of :data:`vfdsl.inputs.INPUT_TYPES`."""

    name: str
    type: Literal[tuple(INPUT_TYPES)]
    span: Span

    @property
    def size(self) -> int:
        return INPUT_TYPES[self.type].size


class ParamDecl(_Model):
    """A reference value that may change at run time; ``frame`` names a pose param it is expressed in."""

    name: str
    type: str                        # point, direction, line, plane, pose, curve, vector, length, angle, ...
    value: Value
    frame: str | None = None
    span: Span
    value_span: Span | None = None   # where the value is written: the task's default, or the scene file


# --------------------------------------------------------------------------------- constraints, objectives

class Constraint(_Model):
    """One ``require`` statement, resolved: a primitive applied to a task frame (or to the joints)."""

    primitive: str
    frame: str | None
    args: dict[str, Arg]
    tolerance: float | None = None   # SI (m or rad); None for primitives without one
    resolution: list[int] | None = None
    soft: bool = False
    weight: float | None = None      # slack weight of a soft constraint
    priority: int | None = None      # level of a soft constraint's slack term (1 = solved first)
    span: Span
    via: list[Span] = []
    arg_spans: dict[str, Span] = {}  # where each argument given was written (a fixture's: at its use)


class Objective(_Model):
    """One ``minimize`` term: weight * || E dq/dt - f ||^2 (a rate error), solved at level ``priority``."""

    term: str
    args: dict[str, Arg]
    weight: float
    priority: int = 1                # 1 = solved first; a larger level acts in the optimal set of the smaller ones
    span: Span
    via: list[Span] = []
    arg_spans: dict[str, Span] = {}  # where each argument given was written (a fixture's: at its use)


# ------------------------------------------------------------------------------------------------ procedures

class FrameMeasure(_Model):
    """A frame's origin (``position``: a point, m), its tool axis (``axis``: a unit direction) or its pose (``pose``:
    [origin; roll, pitch, yaw], a pose param's layout), in the world."""

    ref: Literal["frame_measure"] = "frame_measure"
    frame: str
    part: Literal["position", "axis", "pose"]


class Capture(_Model):
    """``capture NAME = SOURCE``: the source's value taken at the tick the phase is entered. ``kind``: point,
    direction, an input type, or the captured param's type."""

    name: str
    kind: str
    source: Annotated[Union[FrameMeasure, InputRef, ParamRef], Field(discriminator="ref")]
    span: Span


class Distance(_Model):
    """|frame origin - geometry| (m): to a point, a line or a plane (signed: + on the plane's free side)."""

    measure: Literal["distance"] = "distance"
    frame: str
    to: Arg


class Angle(_Model):
    """The angle between the frame's tool axis and a direction (rad, in [0, pi])."""

    measure: Literal["angle"] = "angle"
    frame: str
    direction: Arg


class Norm(_Model):
    """|u| of an input, or of its linear or angular part (the part's unit)."""

    measure: Literal["norm"] = "norm"
    input: str
    part: Literal["all", "linear", "angular"] = "all"


class Elapsed(_Model):
    """Seconds since the current phase was entered."""

    measure: Literal["elapsed"] = "elapsed"


class Unchanged(_Model):
    """Seconds since the input's value last changed; as a condition: unchanged since the previous tick."""

    measure: Literal["unchanged"] = "unchanged"
    input: str


class LeastViolation(_Model):
    """The controller's status at the previous tick: true when it fell back to least violation."""

    measure: Literal["least_violation"] = "least_violation"


class Button(_Model):
    """A button input: true when pressed (its value above 1/2)."""

    measure: Literal["button"] = "button"
    input: str


Measure = Annotated[Union[Distance, Angle, Norm, Elapsed, Unchanged, LeastViolation, Button],
                    Field(discriminator="measure")]


class Compare(_Model):
    """``measure op threshold``, SI; ``release`` (hysteresis): once on, it stays on until the measure passes
    ``release`` (on the off side of ``threshold``); ``dimension``: the measure's (units.describe's word)."""

    expr: Literal["compare"] = "compare"
    measure: Measure
    op: Literal["<", ">", "<=", ">="]
    threshold: float
    release: float | None = None
    dimension: str
    span: Span


class Flag(_Model):
    """A measure that is a condition itself: a button, least_violation, unchanged (since the previous tick)."""

    expr: Literal["flag"] = "flag"
    measure: Measure
    span: Span


class And(_Model):
    expr: Literal["and"] = "and"
    items: list["MonitorExpr"] = Field(min_length=2)


class Or(_Model):
    expr: Literal["or"] = "or"
    items: list["MonitorExpr"] = Field(min_length=2)


class Not(_Model):
    expr: Literal["not"] = "not"
    items: list["MonitorExpr"] = Field(min_length=1, max_length=1)


class MonitorRef(_Model):
    expr: Literal["monitor"] = "monitor"
    name: str


MonitorExpr = Annotated[Union[Compare, Flag, And, Or, Not, MonitorRef], Field(discriminator="expr")]
for _node in (And, Or, Not):
    _node.model_rebuild()


def expression_leaves(expr):
    """The leaves of a monitor expression (comparisons, flags, references to monitors), left to right."""
    if isinstance(expr, (And, Or, Not)):
        for item in expr.items:
            yield from expression_leaves(item)
    else:
        yield expr


class Monitor(_Model):
    """``monitor NAME = EXPR [for HOLD]``: true once EXPR has held for ``hold`` seconds (0: at once);
    ``text``: EXPR as written."""

    name: str
    expr: MonitorExpr
    hold: float = 0.0
    text: str
    span: Span


class Phase(_Model):
    """A phase's own statements (the task's phase-less ones hold in every phase) and its captures."""

    name: str
    initial: bool = False
    final: bool = False
    constraints: list[Constraint] = []
    objectives: list[Objective] = []
    captures: list[Capture] = []
    span: Span


class Transition(_Model):
    """``transition SOURCE -> TARGET when GUARD``: ``source`` None is ``*`` (every phase but a final one and the
    target); ``blend`` (s) its own or the task's; ``order``: its place in the file (the first that holds fires);
    ``text``: the guard as written."""

    source: str | None
    target: str
    guard: MonitorExpr
    blend: float = 0.0
    order: int
    text: str
    span: Span


class Scene(_Model):
    """Data kept outside the task's logic: where it starts and how fast it ticks."""

    file: str | None = None
    start: list[float] | None = None  # joint coordinates (m or rad), in the robot's joint order
    period: float | None = None       # control period in seconds


class Task(_Model):
    name: str
    file: str
    robots: list[RobotDecl]
    frames: list[FrameDecl]
    inputs: list[InputDecl]
    params: list[ParamDecl]
    objectives: list[Objective]
    constraints: list[Constraint]
    scene: Scene = Scene()
    imports: list[str] = []
    span: Span
    phases: list[Phase] = []          # empty: a task without a procedure
    monitors: list[Monitor] = []
    transitions: list[Transition] = []
    blend: float = 0.0                # s: the default blend time of a transition

    @model_serializer(mode="wrap")
    def _serialize(self, handler):
        """A task without a procedure serializes as it did before procedures existed (same JSON, same hash)."""
        data = handler(self)
        for key in ("phases", "monitors", "transitions", "blend"):
            if not getattr(self, key):
                data.pop(key, None)
        return data

    @property
    def start(self) -> np.ndarray | None:
        """The scene's start configuration, or None when the scene gives none."""
        return None if self.scene.start is None else np.array(self.scene.start, dtype=float)

    @property
    def every_constraint(self) -> list[Constraint]:
        """The phase-less constraints, then each phase's, in file order."""
        return [*self.constraints, *(c for phase in self.phases for c in phase.constraints)]

    @property
    def every_objective(self) -> list[Objective]:
        """The phase-less objectives, then each phase's, in file order."""
        return [*self.objectives, *(o for phase in self.phases for o in phase.objectives)]

    def frame(self, name: str) -> FrameDecl:
        return next(f for f in self.frames if f.name == name)

    def param(self, name: str) -> ParamDecl:
        return next(p for p in self.params if p.name == name)

    def input(self, name: str) -> InputDecl:
        return next(i for i in self.inputs if i.name == name)


def checked_task(value, caller: str) -> Task:
    """``value`` when it is a :class:`Task`; otherwise a VfError saying that ``caller`` takes what
    ``vfdsl.load`` returns (a path, or anything else, is not loaded here)."""
    if isinstance(value, Task):
        return value
    given = f"the path {str(value)!r}" if isinstance(value, (str, os.PathLike)) else f"a {type(value).__name__}"
    hint = (f"load it first: vfdsl.{caller}(vfdsl.load({str(value)!r}))" if isinstance(value, (str, os.PathLike))
            else "pass the task vfdsl.load(path) returns")
    raise VfError(f"{caller}() takes a task loaded by vfdsl.load, got {given}", hint=hint)
