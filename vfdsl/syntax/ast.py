"""The surface syntax tree: what a ``.vf`` file says, before any name, unit or shape is checked.

Every node is a pydantic model with a :class:`~vfdsl.errors.Span`, so later passes can point at the exact text.
Values keep their units as written; :mod:`vfdsl.passes` turns them into SI numbers.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field

from vfdsl.errors import Span


class Node(BaseModel):
    model_config = ConfigDict(frozen=True)
    span: Span


class Name(Node):
    """An identifier as written, with its position."""

    text: str


# ---------------------------------------------------------------------------------------------- values

class Quantity(Node):
    node: Literal["quantity"] = "quantity"
    number: float
    unit: str | None = None          # e.g. "mm", "deg/s/N/mm"; None = the file's default unit


class Vector(Node):
    node: Literal["vector"] = "vector"
    items: list["Value"]
    unit: str | None = None          # applies to items written without a unit


class KeywordArg(Node):
    name: Name
    value: "Value"


class Call(Node):
    node: Literal["call"] = "call"
    name: Name
    args: list["Value"] = []
    kwargs: list[KeywordArg] = []


class NameRef(Node):
    node: Literal["name"] = "name"
    name: str


class BinOp(Node):
    """``left + right``, ``left - right`` or ``left * right`` (derived geometry, :mod:`vfdsl.passes.expressions`)."""

    node: Literal["binop"] = "binop"
    op: Literal["+", "-", "*"]
    left: "Value"
    right: "Value"


class Neg(Node):
    """``-operand``."""

    node: Literal["neg"] = "neg"
    operand: "Value"


class String(Node):
    node: Literal["string"] = "string"
    text: str


class Bool(Node):
    node: Literal["bool"] = "bool"
    value: bool


Value = Annotated[Union[Quantity, Vector, Call, NameRef, BinOp, Neg, String, Bool], Field(discriminator="node")]


# ------------------------------------------------------------------------------------------ statements

class Resolution(Node):
    counts: list[int]                # [n] for a polygon, [n, m] for a sphere


class Clauses(BaseModel):
    """The trailing clauses of a minimize/require/use statement."""

    model_config = ConfigDict(frozen=True)
    within: Value | None = None
    resolution: Resolution | None = None
    weight: Value | None = None
    priority: Value | None = None    # level of an objective term or a soft constraint (1 = solved first)
    soft: Span | None = None         # where `soft` was written


class UnitsStmt(Node):
    kind: Literal["units"] = "units"
    names: list[Name]


class ImportStmt(Node):
    kind: Literal["import"] = "import"
    path: str


class SceneStmt(Node):
    kind: Literal["scene"] = "scene"
    path: str


class RobotStmt(Node):
    kind: Literal["robot"] = "robot"
    name: Name
    urdf: str


class FrameStmt(Node):
    """``frame NAME = ROBOT.link("LINK") clauses`` or ``frame NAME = BASE clauses`` (a frame from a frame)."""

    kind: Literal["frame"] = "frame"
    name: Name
    robot: Name | None = None        # with link: a frame on a robot link
    link: Name | None = None
    base: Name | None = None         # or: a frame composed with an earlier frame
    offset: Value | None = None
    rotate: Value | None = None
    axis: Value | None = None


class InputStmt(Node):
    kind: Literal["input"] = "input"
    name: Name
    type: Name


class ParamStmt(Node):
    kind: Literal["param"] = "param"
    name: Name
    type: Name
    type_args: list[KeywordArg] = []
    frame: Name | None = None
    default: Value | None = None


class MinimizeStmt(Node):
    kind: Literal["minimize"] = "minimize"
    call: Call
    clauses: Clauses = Clauses()
    via: list[Span] = []             # the `use` sites this statement was expanded through, outermost first


class RequireStmt(Node):
    kind: Literal["require"] = "require"
    subject: Name | None             # the task frame, or None for whole-robot constraints (joint limits, ...)
    call: Call
    clauses: Clauses = Clauses()
    via: list[Span] = []


class UseStmt(Node):
    kind: Literal["use"] = "use"
    call: Call
    clauses: Clauses = Clauses()
    via: list[Span] = []


class Formal(Node):
    name: Name
    type: Name
    default: Value | None = None


BodyStatement = Annotated[Union[MinimizeStmt, RequireStmt, UseStmt], Field(discriminator="kind")]


class FixtureDef(Node):
    kind: Literal["fixture"] = "fixture"
    name: Name
    formals: list[Formal]
    body: list[BodyStatement]


# ------------------------------------------------------------------------------------------- procedures

class Member(Node):
    """``NAME.FIELD`` in a measure's arguments: ``f.linear``."""

    node: Literal["member"] = "member"
    base: Name
    field: Name


class Measure(Node):
    """What a condition reads: a call (``distance(tip, entry)``) or a name (``elapsed``, a button, a monitor)."""

    name: Name
    args: list[Annotated[Union[Quantity, Vector, Call, NameRef, BinOp, Neg, String, Bool, Member],
                         Field(discriminator="node")]] | None = None     # None: a name, not a call


class Comparison(Node):
    cond: Literal["compare"] = "compare"
    measure: Measure
    op: Literal["<", ">", "<=", ">="]
    threshold: Value
    release: Value | None = None


class Test(Node):
    """A measure that is itself a condition."""

    cond: Literal["test"] = "test"
    measure: Measure


class Logic(Node):
    cond: Literal["and", "or", "not"]
    items: list["Condition"]


Condition = Annotated[Union[Comparison, Test, Logic], Field(discriminator="cond")]
Logic.model_rebuild()


class MonitorStmt(Node):
    kind: Literal["monitor"] = "monitor"
    name: Name
    condition: Condition
    text: str                        # the condition as written, spaces collapsed
    hold: Value | None = None        # `for DURATION`


class CaptureStmt(Node):
    """``capture NAME = SOURCE[.FIELD]``."""

    kind: Literal["capture"] = "capture"
    name: Name
    source: Name
    field: Name | None = None


class PhaseStmt(Node):
    kind: Literal["phase"] = "phase"
    name: Name
    initial: Span | None = None
    final: Span | None = None
    body: list[Annotated[Union[MinimizeStmt, RequireStmt, UseStmt, CaptureStmt], Field(discriminator="kind")]]


class TransitionStmt(Node):
    kind: Literal["transition"] = "transition"
    source: Name | None              # None: `*`, from any phase
    source_span: Span
    target: Name
    guard: Condition
    guard_text: str                  # the guard as written, spaces collapsed
    blend: Value | None = None


class BlendStmt(Node):
    kind: Literal["blend"] = "blend"
    value: Value


Statement = Annotated[
    Union[UnitsStmt, ImportStmt, SceneStmt, RobotStmt, FrameStmt, InputStmt, ParamStmt, FixtureDef,
          MinimizeStmt, RequireStmt, UseStmt, MonitorStmt, PhaseStmt, TransitionStmt, BlendStmt],
    Field(discriminator="kind"),
]


class Module(Node):
    """One parsed file: a task or a library of fixtures."""

    file: str
    header: Literal["task", "library"]
    name: Name
    statements: list[Statement]
