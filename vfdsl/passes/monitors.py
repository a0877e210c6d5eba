"""Monitors and conditions: ``monitor NAME = CONDITION [for DURATION]`` and the guards of transitions, checked
into :class:`~vfdsl.ir.model.MonitorExpr` (numbers in SI).

A condition is a comparison ``MEASURE OP THRESHOLD [release VALUE]``, a measure that is a condition itself (a
button, ``least_violation``, ``unchanged(INPUT)``, a monitor's name), or ``and``/``or``/``not`` of conditions.
The measures and their dimensions:

    distance(FRAME, GEOMETRY)   length   the frame's origin to a point, line or plane
    angle(FRAME, DIRECTION)     angle    the frame's tool axis to a direction
    norm(INPUT[.linear|.angular])        the part's unit (an input of two parts needs the part)
    elapsed                     time     in the current phase
    unchanged(INPUT)            time     since the input's value last changed

A threshold, a ``release`` and a ``for`` are literals of the measure's dimension (a time for ``for``); a
``release`` lies strictly on the off side of its threshold (above it for ``<``, below for ``>``), so the
comparison switches on at the threshold and off at the release. Monitors may name monitors, declared before or
after, but not in a cycle. Each monitor is checked on its own (:mod:`vfdsl.passes.diagnostics`).
"""

from __future__ import annotations

from vfdsl import limits
from vfdsl import units as u
from vfdsl.errors import VfError, suggest
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.passes import fixtures as fx
from vfdsl.passes.diagnostics import Dependent
from vfdsl.passes.expressions import dimension_name
from vfdsl.passes.shapes import LiteralReader
from vfdsl.syntax import ast

STATUS = "least_violation"
ELAPSED = "elapsed"
RESERVED = (STATUS, ELAPSED)
_MEASURES = ("distance", "angle", "norm", "unchanged")
_GEOMETRY_CALLS = {"line": "line", "plane": "plane"}


class Conditions:
    """Reads conditions for one task: ``resolver`` resolves names and values (its ``evaluate``, ``lookup``,
    ``arg_kind``, ``inputs``, ``units``); ``monitors``: every monitor's name (a condition may name any)."""

    def __init__(self, resolver, monitors: set[str]):
        self.resolver = resolver
        self.monitors = monitors
        self.scope = fx.Scope(units=resolver.units, captures=True)

    # ---------------------------------------------------------------------------------------- monitors
    def monitor(self, stmt: ast.MonitorStmt) -> ir.Monitor:
        hold = 0.0 if stmt.hold is None else self.duration(stmt.hold, "a `for`", positive=True)
        return ir.Monitor(name=stmt.name.text, expr=self.condition(stmt.condition), hold=hold,
                          text=stmt.text, span=stmt.span)

    def duration(self, value: ast.Value, what: str, positive: bool) -> float:
        """A `for` (``positive``) or a `blend` duration, s, in (0 or [0, limits.PROCEDURE_DURATION]."""
        seconds = self.threshold(value, u.TIME, what)
        if seconds < 0 or (positive and seconds == 0) or seconds > limits.PROCEDURE_DURATION:
            low = "above 0" if positive else "at least 0"
            raise VfError(f"{what} duration must be {low} and at most {limits.PROCEDURE_DURATION:g} s, got {seconds:g} s",
                          value.span, code="E402")
        return seconds

    def threshold(self, value: ast.Value, dim: u.Dim, what: str) -> float:
        """A literal of dimension ``dim`` (SI)."""
        if isinstance(value, ast.Quantity) and value.unit is not None:
            written = u.parse_unit(value.unit, value.span)[0]
            if written != dim:
                raise VfError(f"{what} is {u.describe(dim)}, but {value.number:g} {value.unit} is "
                              f"{u.describe(written)}", value.span, hint=f"write {u.example(dim)}", code="E806")
        return LiteralReader(self.resolver.units, self.resolver.no_names).scalar(value, dim, what)

    @staticmethod
    def cycles(monitors: list[ir.Monitor]) -> None:
        """Monitors that name each other in a cycle: an error at the cycle's first monitor (in file order).
        Monitors that name no unfinished monitor are removed until none is left, or only cycles and what
        leads into them; from the first of those, following names reaches a cycle."""
        named = {m.name: m for m in monitors}
        remaining = {n: [r for r in _refs(m.expr) if r in named] for n, m in named.items()}
        while True:
            done = [n for n, refs in remaining.items() if not any(r in remaining for r in refs)]
            if not done:
                break
            for n in done:
                del remaining[n]
        if not remaining:
            return
        path = [next(iter(remaining))]
        while True:
            following = next(r for r in remaining[path[-1]] if r in remaining)
            if following in path:
                loop = path[path.index(following):] + [following]
                raise VfError(f"monitors name each other in a cycle: {' -> '.join(loop)}", named[following].span,
                              hint="a monitor may name other monitors, but none may depend on itself", code="E808")
            path.append(following)

    # -------------------------------------------------------------------------------------- conditions
    def condition(self, cond: ast.Condition) -> ir.MonitorExpr:
        if isinstance(cond, ast.Logic):
            items = [self.condition(item) for item in cond.items]
            return {"and": ir.And, "or": ir.Or, "not": ir.Not}[cond.cond](items=items)
        if isinstance(cond, ast.Test):
            return self._test(cond)
        return self._compare(cond)

    def _test(self, cond: ast.Test) -> ir.MonitorExpr:
        measure = cond.measure
        name = measure.name.text
        if measure.args is None and name in self.monitors:
            return ir.MonitorRef(name=name)
        read = self._measure(measure)
        if isinstance(read, tuple) and isinstance(read[0], ir.Unchanged):     # unchanged since the previous tick
            return ir.Flag(measure=read[0], span=cond.span)
        if isinstance(read, tuple):
            dim = read[1]
            raise VfError(f"{_written(measure)} is {u.describe(dim)}, not a condition", measure.span,
                          hint=f"compare it: {_written(measure)} > {u.example(dim)}", code="E811")
        return ir.Flag(measure=read, span=cond.span)

    def _compare(self, cond: ast.Comparison) -> ir.Compare:
        measure = cond.measure
        read = self._measure(measure) if not (measure.args is None and measure.name.text in self.monitors) else None
        if not isinstance(read, tuple):
            raise VfError(f"{_written(measure)} is a condition, not a quantity: it cannot be compared",
                          measure.span, hint=f"write it alone: ... when {_written(measure)}", code="E811")
        arg, dim = read
        what = f"{_written(measure)} ({dimension_name(dim)})"
        threshold = self.threshold(cond.threshold, dim, what)
        release = None
        if cond.release is not None:
            release = self.threshold(cond.release, dim, f"the release of {what}")
            below = cond.op in ("<", "<=")
            if (release <= threshold) if below else (release >= threshold):
                side = "above" if below else "below"
                raise VfError(f"the release of `{_written(measure)} {cond.op} ...` must lie {side} its threshold "
                              f"(it switches off there), got {release:g} for {threshold:g} (SI)", cond.release.span,
                              hint=f"e.g. `< 1 mm release 1.5 mm`: on below 1 mm, off again above 1.5 mm",
                              code="E806")
        return ir.Compare(measure=arg, op=cond.op, threshold=threshold, release=release,
                          dimension=dimension_name(dim), span=cond.span)

    # ---------------------------------------------------------------------------------------- measures
    def _measure(self, measure: ast.Measure) -> ir.Measure | tuple[ir.Measure, u.Dim]:
        """A measure: a condition (a Flag's measure), or (measure, dimension) for a quantity."""
        name = measure.name.text
        if measure.args is None:
            if name == ELAPSED:
                return ir.Elapsed(), u.TIME
            if name == STATUS:
                return ir.LeastViolation()
            if name in self.resolver.inputs:
                kind = self.resolver.inputs[name].type
                if not INPUT_TYPES[kind].switch:
                    raise VfError(f"input '{name}' is a {kind}, not a condition", measure.span,
                                  hint=f"compare its size: norm({name}) > ..." if INPUT_TYPES[kind].moves
                                  else "only a button input is a condition by itself", code="E811")
                return ir.Button(input=name)
            if name in self.resolver.failed:
                raise Dependent
            known = sorted(self.monitors | set(RESERVED) |
                           {n for n, d in self.resolver.inputs.items() if INPUT_TYPES[d.type].switch})
            raise VfError(f"unknown monitor or measure '{name}'", measure.span,
                          hint=suggest(name, known, "monitors, measures and buttons"), code="E807")
        if name not in _MEASURES:
            raise VfError(f"unknown measure '{name}(...)'", measure.name.span,
                          hint=suggest(name, _MEASURES, "measures") + "; and elapsed, least_violation", code="E807")
        args = measure.args
        count = 1 if name in ("norm", "unchanged") else 2
        if len(args) != count:
            raise VfError(f"{name}(...) takes {count} argument{'s' if count > 1 else ''}, got {len(args)}",
                          measure.span, code="E501")
        members = [a for a in args if isinstance(a, ast.Member)]
        if members and name != "norm":
            raise VfError(f"`.{members[0].field.text}` is read only by norm(...)", members[0].span, code="E811")
        if name == "norm":
            return self._norm(args[0])
        if name == "unchanged":
            return ir.Unchanged(input=self._input(args[0]).name), u.TIME
        frame = self.resolver.evaluate(args[0], "frame", self.scope).name
        if name == "angle":
            return ir.Angle(frame=frame, direction=self.resolver.evaluate(args[1], "direction", self.scope)), u.ANGLE
        return ir.Distance(frame=frame, to=self._geometry(args[1])), u.LENGTH

    def _input(self, value: ast.Value) -> ir.InputRef:
        return self.resolver.evaluate(value, "input", self.scope)

    def _norm(self, value) -> tuple[ir.Norm, u.Dim]:
        """|u| of an input or of one part; the dimension of that part."""
        base = value.base if isinstance(value, ast.Member) else None
        ref = self._input(ast.NameRef(span=base.span, name=base.text) if base is not None else value)
        kind = INPUT_TYPES[self.resolver.inputs[ref.name].type]
        if base is None:
            if len(kind.parts) > 1:
                raise VfError(f"input '{ref.name}' is a {kind.name}: its parts have different units", value.span,
                              hint=f"norm({ref.name}.linear) or norm({ref.name}.angular)", code="E811")
            return ir.Norm(input=ref.name), kind.parts[0].dimension
        part = value.field.text
        chosen = {"linear": kind.linear, "angular": kind.angular}.get(part)
        if chosen is None:
            have = [p for p in ("linear", "angular") if getattr(kind, p) is not None]
            raise VfError(f"a {kind.name} input has no part '{part}'", value.field.span,
                          hint=f"its parts: {', '.join(have) or 'none (norm of the input itself)'}", code="E811")
        return ir.Norm(input=ref.name, part=part), chosen.dimension

    def _geometry(self, value: ast.Value) -> ir.Arg:
        """A point, line or plane to measure a distance to."""
        if isinstance(value, ast.NameRef):
            arg = self.resolver.lookup(value, "point", self.scope)
            kind = self.resolver.arg_kind(arg)
            if kind not in ("point", "line", "plane"):
                raise VfError(f"distance(...) measures to a point, a line or a plane; '{value.name}' is a {kind}",
                              value.span, code="E203")
            return arg
        kind = _GEOMETRY_CALLS.get(value.name.text, "point") if isinstance(value, ast.Call) else "point"
        return self.resolver.evaluate(value, kind, self.scope)


def _refs(expr: ir.MonitorExpr) -> list[str]:
    """The monitors an expression names, directly."""
    if isinstance(expr, ir.MonitorRef):
        return [expr.name]
    return [name for item in getattr(expr, "items", []) for name in _refs(item)]


def _written(measure: ast.Measure) -> str:
    if measure.args is None:
        return measure.name.text
    return f"{measure.name.text}(...)"
