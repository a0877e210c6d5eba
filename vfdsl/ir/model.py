"""The checked IR: a task with every name resolved, every number in SI units (m, rad, s, N) and every
shape checked. This is exactly what the compiler sees, and what ``vfdsl show`` prints.

Each declaration, constraint and objective keeps the :class:`~vfdsl.errors.Span` it came from;
statements expanded from a fixture also keep ``via``, the chain of ``use`` sites that produced them.
The IR round-trips through JSON: ``Task.model_validate_json(task.model_dump_json()) == task``.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from vfdsl.errors import Span
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


Value = Annotated[
    Union[PointValue, VectorValue, DirectionValue, LineValue, PlaneValue, PoseValue, CurveValue, MeshValue,
          ScalarValue, FlagValue],
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


Arg = Annotated[Union[ParamRef, FrameRef, InputRef, Const, Derived], Field(discriminator="ref")]
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


class Objective(_Model):
    """One ``minimize`` term: weight * || E dq/dt - f ||^2 (a rate error), solved at level ``priority``."""

    term: str
    args: dict[str, Arg]
    weight: float
    priority: int = 1                # 1 = solved first; a larger level acts in the optimal set of the smaller ones
    span: Span
    via: list[Span] = []


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

    @property
    def start(self) -> np.ndarray | None:
        """The scene's start configuration, or None when the scene gives none."""
        return None if self.scene.start is None else np.array(self.scene.start, dtype=float)

    def frame(self, name: str) -> FrameDecl:
        return next(f for f in self.frames if f.name == name)

    def param(self, name: str) -> ParamDecl:
        return next(p for p in self.params if p.name == name)

    def input(self, name: str) -> InputDecl:
        return next(i for i in self.inputs if i.name == name)
