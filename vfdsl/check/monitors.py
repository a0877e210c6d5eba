"""Where a procedure's conditions can hold: each condition as a union of boxes over its measures, decided from the
comparisons alone (conservatively: what this module says cannot hold, cannot).

A condition is put in disjunctive normal form, each term a box: per measure an interval of values (the
comparisons on it, intersected with the measure's own range: a distance to a point or a line and a norm in
[0, inf), an angle in [0, pi], a time in [0, inf); a distance to a plane is signed), and per flag (a button,
``least_violation``, ``unchanged`` since the previous tick, a held monitor) a truth value. A term holds
somewhere iff every interval is non-empty and no flag is asked both ways; relations between different
measures are not modelled, so two terms of different measures always can hold together.

A latched comparison ``d < t release r`` is on wherever d < r (it switched on below t and has not passed r), and
off wherever d >= t; a monitor with a ``for`` is true only where its condition holds, and ``m`` and ``not m``
never hold together. Measures are the same when they measure the same thing: two frames with one origin (same
link and offset) have one distance to a geometry, two with one tool axis one angle.

Findings here: a comparison or a monitor that can never hold (VF954) or always holds (VF955).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.ir import model as ir
from vfdsl.limits import PROCEDURE_DURATION

MAX_TERMS = 256
"""Terms of a normal form beyond which a condition is taken to hold anywhere (conservative)."""


@dataclass(frozen=True)
class Interval:
    lo: float = -math.inf
    hi: float = math.inf
    lo_closed: bool = False
    hi_closed: bool = False

    @property
    def empty(self) -> bool:
        if math.isnan(self.lo) or math.isnan(self.hi):
            return True
        return self.lo > self.hi or (self.lo == self.hi and not (self.lo_closed and self.hi_closed))

    def __and__(self, other: Interval) -> Interval:
        lo, lo_open = max((self.lo, not self.lo_closed), (other.lo, not other.lo_closed))
        hi, hi_closed = min((self.hi, self.hi_closed), (other.hi, other.hi_closed))
        return Interval(lo, hi, not lo_open, hi_closed)

    def __or__(self, other: Interval) -> Interval:
        """The hull of both."""
        if self.empty or other.empty:
            return other if self.empty else self
        lo, lo_open = min((self.lo, not self.lo_closed), (other.lo, not other.lo_closed))
        hi, hi_closed = max((self.hi, self.hi_closed), (other.hi, other.hi_closed))
        return Interval(lo, hi, not lo_open, hi_closed)


NEVER = Interval(math.nan, math.nan)
Term = tuple[dict, dict]
"""(measure key -> Interval, flag key -> bool) of one term of a normal form."""


# ------------------------------------------------------------------------------------------------ measures
def arg_key(arg) -> str:
    """An argument or measure, spans left out: equal keys, equal values."""
    def strip(value):
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if k != "span"}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value
    return json.dumps(strip(arg.model_dump(mode="json")), sort_keys=True)


def origin(task: ir.Task, frame: str) -> tuple:
    f = task.frame(frame)
    return f.robot, f.link, tuple(f.offset)


def axis(task: ir.Task, frame: str) -> tuple:
    f = task.frame(frame)
    return f.robot, f.link, tuple(f.rpy), tuple(f.tool_axis)


def measure_key(task: ir.Task, m: ir.Measure) -> tuple:
    """The measure, frames named by what of them it reads (origin or tool axis)."""
    if isinstance(m, ir.Distance):
        return "distance", origin(task, m.frame), arg_key(m.to)
    if isinstance(m, ir.Angle):
        return "angle", axis(task, m.frame), arg_key(m.direction)
    return (arg_key(m),)


def geometry_kind(task: ir.Task, arg: ir.Arg) -> str | None:
    """point, line, plane ... of an argument; None when unknown."""
    if isinstance(arg, ir.Const):
        return arg.value.kind
    if isinstance(arg, ir.Derived):
        return arg.kind
    if isinstance(arg, ir.ParamRef):
        return task.param(arg.name).type
    if isinstance(arg, ir.CaptureRef):
        return next((c.kind for p in task.phases for c in p.captures if c.name == arg.name), None)
    return None


def measure_range(task: ir.Task, m: ir.Measure) -> Interval:
    """The values the measure can take."""
    if isinstance(m, ir.Angle):
        return Interval(0.0, math.pi, True, True)
    if isinstance(m, ir.Distance) and geometry_kind(task, m.to) not in ("point", "line"):
        return Interval()                                   # signed (a plane) or unknown
    return Interval(0.0, math.inf, True, False)


def range_words(task: ir.Task, m: ir.Measure) -> str:
    if isinstance(m, ir.Angle):
        return "an angle lies in [0, 180] deg"
    if isinstance(m, ir.Distance):
        return f"a distance to a {geometry_kind(task, m.to)} is at least 0"
    return f"{'a norm' if isinstance(m, ir.Norm) else 'a time'} is at least 0"


def _below(t: float, closed: bool) -> Interval:
    return Interval(hi=t, hi_closed=closed)


def _above(t: float, closed: bool) -> Interval:
    return Interval(lo=t, lo_closed=closed)


def switch_on(c: ir.Compare) -> Interval:
    """Where the comparison as written (its threshold, no latch) holds."""
    closed = c.op in ("<=", ">=")
    return _below(c.threshold, closed) if c.op in ("<", "<=") else _above(c.threshold, closed)


def on_values(c: ir.Compare) -> Interval:
    """Where the comparison is (or, latched, can still be) on: below (above) its release once switched on."""
    if c.release is None:
        return switch_on(c)
    return _below(c.release, False) if c.op in ("<", "<=") else _above(c.release, False)


def off_values(c: ir.Compare) -> Interval:
    """Where the comparison is (or, latched, can still be) off: not below (above) its threshold."""
    closed = c.release is not None or c.op in ("<", ">")
    return _above(c.threshold, closed) if c.op in ("<", "<=") else _below(c.threshold, closed)


def switch_off(c: ir.Compare) -> Interval:
    """Where a latched comparison switches off: at or past its release."""
    return _above(c.release, True) if c.op in ("<", "<=") else _below(c.release, True)


# ------------------------------------------------------------------------------------------------ normal form
class _Forms:
    def __init__(self, task: ir.Task):
        self.task = task
        self.monitors = {m.name: m for m in task.monitors}
        self.ranges: dict[tuple, Interval] = {}

    def terms(self, expr: ir.MonitorExpr, positive: bool = True) -> list[Term] | None:
        """The satisfiable terms of ``expr`` (or of ``not expr``); None: too many to tell."""
        if isinstance(expr, ir.Not):
            return self.terms(expr.items[0], not positive)
        if isinstance(expr, (ir.And, ir.Or)):
            parts = [self.terms(item, positive) for item in expr.items]
            if any(p is None for p in parts):
                return None
            if isinstance(expr, ir.Or) == positive:
                out = [t for p in parts for t in p]
                return out if len(out) <= MAX_TERMS else None
            out = [({}, {})]
            for p in parts:
                out = [m for a in out for b in p if (m := self._merge(a, b)) is not None]
                if len(out) > MAX_TERMS:
                    return None
            return out
        if isinstance(expr, ir.Compare):
            key = measure_key(self.task, expr.measure)
            self.ranges[key] = measure_range(self.task, expr.measure)
            values = NEVER if math.isnan(expr.threshold) else on_values(expr) if positive else off_values(expr)
            return self._filter([({key: values}, {})])
        if isinstance(expr, ir.Flag):
            return [({}, {measure_key(self.task, expr.measure): positive})]
        monitor = self.monitors[expr.name]
        flag = {("monitor", monitor.name): positive}
        if monitor.hold > 0 and not positive:
            return [({}, flag)]
        inner = self.terms(monitor.expr, positive)
        return None if inner is None else [m for t in inner if (m := self._merge(t, ({}, flag))) is not None]

    def _merge(self, a: Term, b: Term) -> Term | None:
        values = dict(a[0])
        for key, v in b[0].items():
            values[key] = values[key] & v if key in values else v
        flags = dict(a[1])
        for key, v in b[1].items():
            if flags.setdefault(key, v) != v:
                return None
        kept = self._filter([(values, flags)])
        return kept[0] if kept else None

    def _filter(self, terms: list[Term]) -> list[Term]:
        return [t for t in terms if not any((v & self.ranges[k]).empty for k, v in t[0].items())]


def can_hold(task: ir.Task, expr: ir.MonitorExpr) -> bool:
    terms = _Forms(task).terms(expr)
    return terms is None or bool(terms)


def always_holds(task: ir.Task, expr: ir.MonitorExpr) -> bool:
    """True when ``not expr`` can never hold (a NaN measure aside)."""
    return _Forms(task).terms(expr, positive=False) == []


def hold_together(task: ir.Task, a: ir.MonitorExpr, b: ir.MonitorExpr) -> bool:
    return can_hold(task, ir.And(items=[a, b]))


def bounds(task: ir.Task, expr: ir.MonitorExpr, measure: ir.Measure) -> Interval:
    """The hull of the values ``measure`` can take where ``expr`` holds (its range on a side ``expr`` does not
    bound; empty when ``expr`` never holds)."""
    terms = _Forms(task).terms(expr)
    full = measure_range(task, measure)
    if terms is None:
        return full
    key = measure_key(task, measure)
    hull = NEVER
    for values, _ in terms:
        hull = hull | (values.get(key, Interval()) & full)
    return hull


# ------------------------------------------------------------------------------------------------ findings
def compares(expr: ir.MonitorExpr):
    """The comparisons written in ``expr`` (not those of monitors it names)."""
    if isinstance(expr, ir.Compare):
        yield expr
    for item in getattr(expr, "items", []):
        yield from compares(item)


def analyse(task: ir.Task) -> list[Finding]:
    """VF954 and VF955 for every comparison, then for every monitor and guard as a whole (a guard that names one
    monitor is judged at the monitor)."""
    findings = []
    for owner, expr, hold in [*((m, m.expr, m.hold) for m in task.monitors),
                              *((t, t.guard, 0.0) for t in task.transitions)]:
        what = f"monitor '{owner.name}'" if isinstance(owner, ir.Monitor) else f"the guard of transition {arrow(owner)}"
        found = [f for c in compares(expr) for f in _comparison(task, c, what)]
        findings += found
        if not 0 <= hold <= PROCEDURE_DURATION:
            findings.append(Finding("monitor-never-true", Severity.ERROR,
                                    f"{what} must hold for {hold:g} s: the longest `for` is {PROCEDURE_DURATION:g} s",
                                    owner.span, "a `for` of seconds at most; is it in the wrong unit?", what,
                                    {"hold": hold, "limit": PROCEDURE_DURATION}))
        elif found or isinstance(expr, ir.MonitorRef):
            continue                                # said at the comparison, or at the monitor named
        elif not can_hold(task, expr):
            findings.append(Finding("monitor-never-true", Severity.ERROR,
                                    f"{what} can never become true: `{owner.text}` asks a measure for values it "
                                    f"cannot have together, or a flag for both truth values", owner.span,
                                    "compare the thresholds on each measure it reads", what, {"hold": hold}))
        elif always_holds(task, expr):
            after = f" (after its `for` of {hold * 1e3:g} ms)" if hold else ""
            findings.append(Finding("monitor-always-true", Severity.WARNING,
                                    f"{what} always holds{after}: `{owner.text}` is true whatever the state",
                                    owner.span, "compare the thresholds with each measure's range", what,
                                    {"hold": hold}))
    return findings


def _comparison(task: ir.Task, c: ir.Compare, what: str) -> list[Finding]:
    """A comparison that never switches on, is never off, or whose latch never switches off."""
    full = measure_range(task, c.measure)
    data = {"threshold": c.threshold, "release": c.release, "range": [full.lo, full.hi]}
    words = range_words(task, c.measure)
    if (switch_on(c) & full).empty or math.isnan(c.threshold):
        return [Finding("monitor-never-true", Severity.ERROR, f"in {what}, `{_written(c)}` can never hold: {words}",
                        c.span, "is the threshold's sign or unit wrong?", what, data)]
    if (off_values(c) & full).empty:
        return [Finding("monitor-always-true", Severity.WARNING, f"in {what}, `{_written(c)}` always holds: {words}",
                        c.span, "is the threshold's sign or unit wrong?", what, data)]
    if c.release is not None and ((switch_off(c) & full).empty or math.isnan(c.release)):
        return [Finding("monitor-always-true", Severity.WARNING,
                        f"in {what}, the release of `{_written(c)}` lies beyond every value the measure can take "
                        f"({words}): once on, the latch never switches off", c.span,
                        "a release just past the threshold, on its off side", what, data)]
    return []


def _written(c: ir.Compare) -> str:
    """The comparison as findings name it: ``distance(tip, entry) < 0 mm``."""
    release = "" if c.release is None else f" release {quantity(c.release, c.dimension)}"
    return f"{describe(c.measure)} {c.op} {quantity(c.threshold, c.dimension)}{release}"


def describe(m: ir.Measure) -> str:
    """``distance(tip, entry)``, ``norm(hand)``, ``elapsed``; a computed argument is written ``...``."""
    def name(arg):
        return getattr(arg, "name", "...")
    if isinstance(m, ir.Distance):
        return f"distance({m.frame}, {name(m.to)})"
    if isinstance(m, ir.Angle):
        return f"angle({m.frame}, {name(m.direction)})"
    if isinstance(m, ir.Norm):
        return f"norm({m.input}{'' if m.part == 'all' else '.' + m.part})"
    if isinstance(m, (ir.Unchanged, ir.Button)):
        return f"{m.measure}({m.input})"
    return m.measure


def arrow(t: ir.Transition) -> str:
    return f"{t.source or '*'} -> {t.target} (line {t.span.line})"
