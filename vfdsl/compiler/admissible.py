"""Admissible run-time values: every check of a task's params, as one column of margins.

    admissible = Admissible(task, robot)
    admissible.function(p) -> margins      # check i holds iff margins[i] is finite and >= 0 (> 0 when strict)

The checks are written and read through one :class:`~vfdsl.compiler.margins.Margins`, and the same Function
serves everywhere: at load time on the task's and scene's values (an error at the value's line), in Python
for ``Controller.step(..., params=...)``, and in the task's generated C (its fast path evaluates the column
and accepts a tick only when every check holds). Each check, in SI units:

- a direction, a line's direction, a plane's normal: ``|d| >= MIN_DIRECTION_NORM`` (it is normalized in the
  step; shorter, it has no direction);
- a point, a vector (a displacement), a line's or plane's point, a pose's translation, each point of a run-time
  curve: every coordinate
  within the task's plausible distance ``L = min(MAX_DISTANCE, REACH_FACTOR x reach)``, reach being the
  robot's (:attr:`vfdsl.kinematics.robot.Robot.reach`) plus the longest task-frame offset; a length param:
  ``|x| <= L``. A value in millimetres read as metres lands beyond it (any coordinate over 3 x the reach in
  mm: 1.9 mm on shr7, 4.3 mm on panda7);
- an angle param, a pose's rpy: within one turn, ``|a| <= 2 pi`` (degrees read as radians land beyond it);
- a scalar param: the range of every argument it feeds (``ArgSpec.range``, as a literal there);
- a run-time curve: consecutive points at least ``MIN_CHORD`` apart, and for a b-spline (its parameters
  fixed from the chords of its default points) each chord within a factor ``CHORD_RATIO`` of its default;
- a derived argument (``normalize(target - entry)``, ``plane(a, cross(u, v))``) of any statement, in every phase
  whichever is active, or of a monitor: every vector it normalizes at least ``derived.MIN_NORM`` long, and its
  value finite (:func:`vfdsl.compiler.derived.add_checks`); one that reads a capture is not a param's.
"""

from __future__ import annotations

import math
from functools import cached_property

import casadi as ca
import numpy as np

from vfdsl.compiler import derived, registry
from vfdsl.compiler.context import ParamReader, ParamSlot
from vfdsl.compiler.geometry import scaled_norm
from vfdsl.compiler.margins import Check, Margins
from vfdsl.errors import show_vector
from vfdsl.ir import model as ir

MIN_DIRECTION_NORM = 1e-12
"""A direction shorter than this (before normalization) is taken for zero, in the task file and at run time."""
MAX_DISTANCE = 10.0
"""No point of a task lies beyond this many metres from the robot's base, whatever the robot."""
REACH_FACTOR = 3.0
"""Points (and lengths) up to this many times the robot's reach are plausible: fixture geometry sits near the
workspace, and a plane or a line may be given by a point somewhat outside it."""
FULL_TURN = 2 * math.pi
MIN_CHORD = 1e-6
"""Shortest distance (m) between consecutive run-time curve points: closer, they are taken for a repeated point."""
CHORD_RATIO = 2.0
"""A run-time b-spline's chords may shrink or grow by at most this factor from its default points' chords."""

_SLIP_M = "run-time values are in metres (millimetres given as metres?)"
_SLIP_RAD = "angles are in radians at run time (degrees given as radians?)"


def plausible_distance(reach: float) -> float:
    """L (m): the largest coordinate plausible for a task whose frames reach ``reach`` from the robot's base."""
    return min(MAX_DISTANCE, REACH_FACTOR * reach)


def task_reach(task: ir.Task, robot_reach: float) -> float:
    """How far from the robot's base a task frame can be (m): the robot's reach and the longest frame offset."""
    return robot_reach + max((float(np.linalg.norm(f.offset)) for f in task.frames), default=0.0)


class Admissible:
    """The checks of one task's run-time params: ``margins`` (the column and its checks) and ``function``."""

    def __init__(self, task: ir.Task, reach: float):
        """``reach``: the robot's (:attr:`vfdsl.kinematics.robot.Robot.reach`)."""
        self.task = task
        self.reach = task_reach(task, reach)
        self.distance = plausible_distance(self.reach)
        reader = ParamReader(task.params)
        self.layout = reader.layout
        self.margins = Margins()
        ranges = _param_ranges(task)
        for decl in task.params:
            slot = reader.layout.slots[decl.name]
            if slot.size:
                self._param(decl, slot, reader.p[slot.offset:slot.offset + slot.size], ranges.get(decl.name, []))
        for arg, notes in _derived_args(task):
            derived.add_checks(self.margins, arg, reader.read, notes)
        self.function = ca.Function("admissible", [reader.p], [self.margins.symbolic()], ["p"], ["margins"])

    @cached_property
    def strict(self) -> np.ndarray:
        return self.margins.strict

    def verify(self, p: np.ndarray, numbers=None, when: str = "") -> None:
        """Raise the VfError of the first check that fails at params ``p`` (``numbers``: the column, if
        already evaluated, e.g. by the generated C)."""
        self.margins.verify(self.function(p) if numbers is None else numbers, p, when)

    def far_constants(self):
        """(span, notes, message) of every constant point written in a statement or a monitor (a point, a line's or a
        plane's point, a curve's points) with a coordinate beyond the plausible distance: the rule a param's point
        meets, so that a point in millimetres read as metres is refused wherever it is written."""
        for statement in [*self.task.every_constraint, *self.task.every_objective]:
            name = statement.primitive if isinstance(statement, ir.Constraint) else statement.term
            notes = tuple(f"in a fixture used at {span}" for span in reversed(statement.via))
            for arg_name, arg in statement.args.items():
                yield from self._far(arg, f"{name}(...) argument '{arg_name}'",
                                     statement.arg_spans.get(arg_name, statement.span), notes)
        for monitor in self.task.monitors:
            for node in ir.expression_leaves(monitor.expr):
                arg = getattr(getattr(node, "measure", None), "to", None)
                yield from self._far(arg, f"monitor '{monitor.name}''s point", monitor.span, ())

    def _far(self, arg, what: str, span, notes: tuple):
        if not isinstance(arg, ir.Const):
            return
        value = arg.value
        for k, xyz in enumerate(_written_points(value)):
            if np.max(np.abs(xyz)) > self.distance:
                part = f"'s point {k + 1}" if value.kind == "curve" else "" if value.kind in ("point", "vector") \
                    else "'s point"
                yield span, notes, f"{what}{part} is {show_vector(xyz)} m: beyond {self._bound_words()}"

    # ------------------------------------------------------------------------------------------ params
    def _param(self, decl: ir.ParamDecl, slot: ParamSlot, x, ranges: list) -> None:
        name, kind = decl.name, decl.type
        what = f"param '{name}'"
        if kind in ("point", "vector", "line", "plane"):
            self._point(name, what if kind in ("point", "vector") else f"{what}'s point", x[0:3], slot.offset)
        if kind in ("direction", "line", "plane"):
            part = {"direction": "", "line": "'s direction", "plane": "'s normal"}[kind]
            d = x[0:3] if kind == "direction" else x[3:6]
            at = slot.offset + (0 if kind == "direction" else 3)
            self.margins.add(scaled_norm(d) - MIN_DIRECTION_NORM, Check(
                lambda m, p, w=what + part, at=at: f"{w} is a zero direction ({show_vector(p[at:at + 3])}, length "
                                                   f"{math.hypot(*p[at:at + 3]):.3g})",
                f"{what}{part} must not be a zero direction", hint="give a non-zero vector, e.g. [0, 0, 1]", param=name))
        if kind == "pose":
            self._point(name, f"{what}'s translation", x[0:3], slot.offset)
            self.margins.add(FULL_TURN - ca.mmax(ca.fabs(x[3:6])), Check(
                lambda m, p, o=slot.offset + 3: f"{what}'s rpy {show_vector(p[o:o + 3])} rad: beyond a full turn",
                f"{what}'s rpy must be within a full turn", hint=_SLIP_RAD, param=name))
        if kind == "length":
            self.margins.add(self.distance - ca.fabs(x[0]), Check(
                lambda m, p, o=slot.offset: f"{what} = {p[o]:.6g} m: beyond {self._bound_words()}",
                f"{what} must be within {self.distance:.3g} m", hint=_SLIP_M, param=name))
        if kind == "angle":
            self.margins.add(FULL_TURN - ca.fabs(x[0]), Check(
                lambda m, p, o=slot.offset: f"{what} = {p[o]:.6g} rad: beyond a full turn",
                f"{what} must be within a full turn", hint=_SLIP_RAD, param=name))
        for allowed, use in ranges:
            self._range(name, x[0], slot.offset, allowed, use)
        if kind == "curve":
            self._curve(name, decl.value, x, slot.offset)

    def _point(self, name: str, what: str, xyz, offset: int) -> None:
        self.margins.add(self.distance - ca.mmax(ca.fabs(xyz)), Check(
            lambda m, p: f"{what} is {show_vector(p[offset:offset + 3])} m: beyond {self._bound_words()}",
            f"{what} must be within {self.distance:.3g} m of the base in every coordinate", hint=_SLIP_M, param=name))

    def _range(self, name: str, x, offset: int, allowed, use: str) -> None:
        def message(m, p):
            return f"param '{name}' = {p[offset]:.6g} (SI) {allowed.violation(float(p[offset]))}, as the {use} it feeds"
        meaning = f"param '{name}', as the {use}, must be {allowed.describe()}"
        if allowed.low is not None:
            self.margins.add(x - allowed.low, Check(message, meaning, strict=allowed.low_open, param=name))
        if allowed.high is not None:
            self.margins.add(allowed.high - x, Check(message, meaning, strict=allowed.high_open, param=name))

    def _curve(self, name: str, default: ir.CurveValue, x, offset: int) -> None:
        what = f"param '{name}'"
        n = len(default.points)
        points = ca.reshape(x, 3, n)
        for k in range(n):
            self._point(name, f"{what}'s point {k + 1}", points[:, k], offset + 3 * k)
        default_chords = np.linalg.norm(np.diff(np.array(default.points), axis=0), axis=1)
        for k in range(n - 1):
            chord = ca.norm_2(points[:, k + 1] - points[:, k])

            def message(m, p, k=k):
                c = float(np.linalg.norm(p[offset + 3 * k + 3:offset + 3 * k + 6] - p[offset + 3 * k:offset + 3 * k + 3]))
                if not c >= MIN_CHORD:
                    return f"{what}'s points {k + 1} and {k + 2} are {c:.3g} m apart: a repeated point"
                ratio = c / default_chords[k]
                return (f"{what}'s points {k + 1} and {k + 2} are {c:.6g} m apart, {ratio:.3g} x their default "
                        f"distance ({default_chords[k]:.6g} m); a run-time b-spline may stretch each span by at "
                        f"most {CHORD_RATIO:g} x")
            hint = (f"consecutive points must be at least {MIN_CHORD:g} m apart" if default.degree == 1 else
                    "its parameters are fixed from the default points: give the curve default points close to "
                    "the shapes it takes, or use degree 1")
            self.margins.add(chord - MIN_CHORD, Check(
                message, f"{what}'s points {k + 1} and {k + 2} must be at least {MIN_CHORD:g} m apart", hint=hint,
                param=name))
            if default.degree > 1:
                ratio = chord / default_chords[k]
                self.margins.add(ca.fmin(ratio - 1 / CHORD_RATIO, CHORD_RATIO - ratio),
                                 Check(message, f"{what}'s points {k + 1} and {k + 2} must stay within "
                                                f"{CHORD_RATIO:g} x their default distance", hint=hint, param=name))

    def _bound_words(self) -> str:
        return (f"{self.distance:.3g} m, the largest coordinate plausible for this task ({REACH_FACTOR:g} x its "
                f"reach of {self.reach:.3g} m, at most {MAX_DISTANCE:g} m)")


def _written_points(value: ir.Value) -> list:
    """The points a constant value is written with: a point's, a vector's (a displacement: no longer than a point may
    lie away), a line's or a plane's point, a curve's (none else)."""
    if value.kind in ("point", "vector"):
        return [value.xyz]
    if value.kind in ("line", "plane"):
        return [value.point]
    return value.points if value.kind == "curve" else []


def _derived_args(task: ir.Task):
    """(derived argument, notes) of every statement, in phases too, and of every monitor's measure: each derived
    from params and constants alone (one that reads a capture has no value until its phase is entered, and the
    params' check runs at every tick, in every phase)."""
    for statement in [*task.every_constraint, *task.every_objective]:
        notes = tuple(f"in a fixture used at {span}" for span in reversed(statement.via))
        yield from ((arg, notes) for arg in statement.args.values() if _of_params(arg))
    for monitor in task.monitors:
        for node in ir.expression_leaves(monitor.expr):
            measure = getattr(node, "measure", None)
            arg = getattr(measure, "to", None) or getattr(measure, "direction", None)
            if _of_params(arg):
                yield arg, (f"in monitor '{monitor.name}' at {monitor.span}",)


def _of_params(arg) -> bool:
    """``arg`` is derived, from params and constants alone."""
    return isinstance(arg, ir.Derived) and not derived.reads_capture(arg)


def _param_ranges(task: ir.Task) -> dict[str, list]:
    """param name -> [(Range, 'argument x of y'), ...]: the allowed range (``ArgSpec.range``) of every
    argument the param feeds, in phases too, so that a run-time value meets the same range as a literal; a param
    captured in a phase (``capture k = param``) feeds what the capture feeds (the capture holds a value the param
    had, checked then)."""
    captured: dict[str, set] = {}
    for phase in task.phases:
        for c in phase.captures:
            if isinstance(c.source, ir.ParamRef):
                captured.setdefault(c.name, set()).add(c.source.name)
    out: dict[str, list] = {}
    for statement in [*task.every_constraint, *task.every_objective]:
        name = statement.primitive if isinstance(statement, ir.Constraint) else statement.term
        lowering = registry.CONSTRAINTS.get(name) or registry.OBJECTIVES.get(name)
        spec = lowering.spec if lowering else None
        for arg_spec in spec.args if spec else ():
            arg = statement.args.get(arg_spec.name)
            allowed = getattr(arg_spec, "range", None)
            if allowed is None:
                continue
            if isinstance(arg, ir.ParamRef):
                out.setdefault(arg.name, []).append((allowed, f"argument '{arg_spec.name}' of {name}"))
            elif isinstance(arg, ir.CaptureRef):
                for param in sorted(captured.get(arg.name, ())):
                    out.setdefault(param, []).append(
                        (allowed, f"argument '{arg_spec.name}' of {name} through the capture '{arg.name}'"))
    return out
