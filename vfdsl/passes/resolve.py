"""Name resolution and checking: syntax tree (+ scene, + libraries) -> the checked :class:`~vfdsl.ir.model.Task`.

The pass reads the task's declarations (:mod:`vfdsl.passes.declarations`), expands fixtures, then checks
every ``require``/``minimize`` call against its
primitive's signature (:mod:`vfdsl.primitives.spec`): argument names and kinds, units (via
:mod:`vfdsl.units`), shapes (via :mod:`vfdsl.passes.shapes`) and the argument's allowed range (for a
literal, at the literal; for a param, at the param's value and naming the use), then the clauses ``within``,
``resolution``, ``soft`` and ``weight`` against :mod:`vfdsl.limits`. Each statement, and each argument and
clause of it, is checked on its own; every mistake found is raised at once, at its position
(:mod:`vfdsl.passes.diagnostics`).
"""

from __future__ import annotations

import math
from pathlib import Path

from vfdsl import limits
from vfdsl import units as u
from vfdsl.errors import VfError, non_finite_name, suggest
from vfdsl.inputs import INPUT_TYPES, described
from vfdsl.ir import model as ir
from vfdsl.objectives import OBJECTIVES
from vfdsl.passes import clause_ranges
from vfdsl.passes import expressions as ex
from vfdsl.passes import fixtures as fx
from vfdsl.passes.calls import bind_arguments
from vfdsl.passes.declarations import Declarations
from vfdsl.passes.diagnostics import Dependent
from vfdsl.passes.procedure import Procedure
from vfdsl.passes.shapes import LiteralReader, describe_kind
from vfdsl.primitives import CONSTRAINTS
from vfdsl.primitives.spec import (
    SCALAR_DIMENSIONS,
    TASK_LEVEL,
    ArgSpec,
    flag,
    gain_dimension,
)
from vfdsl.syntax import ast

DEFAULT_SOFT_WEIGHT = 1.0


def file_units(module: ast.Module) -> u.DefaultUnits:
    """The defaults set by a file's (single) ``units`` statement."""
    statements = [s for s in module.statements if isinstance(s, ast.UnitsStmt)]
    if len(statements) > 1:
        raise VfError("only one `units` statement per file", statements[1].span,
                      hint=f"the first is at {statements[0].span}", code="E303")
    if not statements:
        return u.DefaultUnits()
    return u.default_units([(name.text, name.span) for name in statements[0].names])


class Resolver(Declarations):
    """Builds the IR of one task: its declarations (:class:`~vfdsl.passes.declarations.Declarations`), then
    every ``require``/``minimize`` call, fixtures expanded. Use :func:`resolve`."""

    def __init__(self, module: ast.Module, path: Path, libraries: list[tuple[ast.Module, u.DefaultUnits]]):
        super().__init__(module, path, file_units(module))
        self.libraries = libraries
        self.task_scope = fx.Scope(units=self.units)
        self.captures: dict[str, ir.Capture] = {}
        self.rows = self.constraint_count = 0          # over the whole task, every phase's statements included

    # ----------------------------------------------------------------------------------- entry point
    def run(self, imports: list[str]) -> ir.Task:
        """The task; every independent mistake in its files raised at once (:mod:`vfdsl.passes.diagnostics`)."""
        with self.errors.report():
            return self._task(imports)

    def _task(self, imports: list[str]) -> ir.Task:
        statements = self.module.statements
        scene = self.read()
        fixtures = fx.collect(self.libraries + [(self.module, self.units)], self.errors)
        procedure = Procedure(self, statements)
        self.captures = procedure.declare()
        body = [s for s in statements if isinstance(s, (ast.MinimizeStmt, ast.RequireStmt, ast.UseStmt))]

        def read(statements: list, scope: fx.Scope) -> tuple[list[ir.Objective], list[ir.Constraint]]:
            return self._statements(statements, scope, fixtures)
        objectives, constraints = read(body, self.task_scope)
        phases = procedure.read_phases(read)
        monitors = procedure.read_monitors()
        blend = 0.0
        with self.errors.each():
            blend = procedure.read_blend()
        transitions = procedure.read_transitions(blend)
        robot_decl, robot = next(iter(self.robots.values()), (None, None))
        scene_ir = self.scene_ir(scene, robot)
        self.errors.checkpoint()
        task = ir.Task(
            name=self.module.name.text, file=str(self.path), span=self.module.span,
            robots=[robot_decl], frames=list(self.frames.values()), inputs=list(self.inputs.values()),
            params=list(self.params.values()), objectives=objectives, constraints=constraints,
            scene=scene_ir, imports=imports, phases=phases, monitors=monitors, transitions=transitions, blend=blend)
        self.check_param_values(task, robot)
        return task

    def _statements(self, body: list, scope: fx.Scope, fixtures: fx.Fixtures) \
            -> tuple[list[ir.Objective], list[ir.Constraint]]:
        """The objectives and constraints of ``body`` (fixtures expanded), counted against the task's limits."""
        objectives, constraints = [], []
        for stmt, inner in fx.expand(body, scope, fixtures, self.evaluate, self.errors):
            with self.errors.each(inner.note):
                if isinstance(stmt, ast.MinimizeStmt):
                    objectives.append(self._objective(stmt, inner))
                else:
                    constraints.append(self._constraint(stmt, inner))
                    self.rows += _row_estimate(constraints[-1])
                    self.constraint_count += 1
            if self.constraint_count > limits.CONSTRAINTS:
                raise inner.note(limits.exceeded("too many constraints", limits.CONSTRAINTS, stmt.span, code="E701"))
            if self.rows > limits.ROWS:
                raise inner.note(limits.exceeded(f"too many constraint rows (about {self.rows:,} so far)",
                                                 limits.ROWS, stmt.span, hint="lower the resolution of the polytopes",
                                                 code="E701"))
        return objectives, constraints

    # ------------------------------------------------------------------------------------- names
    def evaluate(self, value: ast.Value, kind: str, scope: fx.Scope, input_type: str | None = None) -> ir.Arg:
        """The IR argument for ``value`` read as ``kind`` in ``scope`` (names resolve lexically)."""
        if isinstance(value, ast.NameRef):
            return self._resolve_name(value, kind, scope)
        if kind in ("frame", "input"):
            raise VfError(f"expected the name of {describe_kind(kind)}", value.span,
                          hint=suggest("", self._names_of(kind, scope), f"{kind}s"), code="E203")
        if kind in ex.KINDS and ex.is_expression(value):
            return ex.Expressions(scope.units, lambda ref: self.lookup(ref, "name", scope), self.arg_kind,
                                  list(self.params.values())).evaluate(value, kind)
        reader = self._scoped_reader(scope)
        if kind in ("gain", "angular_gain"):
            dim = gain_dimension(input_type, kind)
            if dim is None:
                raise VfError(f"a {input_type} input has no {kind.replace('_', ' ')}", value.span,
                              hint="a force drives translation (gain), a torque drives rotation (angular_gain)",
                              code="E503")
            return ir.Const(value=ir.ScalarValue(dimension=kind, value=reader.scalar(value, dim, kind)))
        return ir.Const(value=reader.read(value, kind))

    def _names_of(self, kind: str, scope: fx.Scope) -> list[str]:
        if scope.bindings is not None:
            return list(scope.bindings)
        table = {"frame": self.frames, "input": self.inputs}.get(kind)
        if table is not None:                       # with those whose declaration failed
            return list(table) + [s.name.text for s in self.module.statements
                                  if s.kind == kind and s.name.text in self.failed]
        return [n for n, p in self.params.items() if p.type == kind] or list(self.params)

    def _resolve_name(self, ref: ast.NameRef, kind: str, scope: fx.Scope) -> ir.Arg:
        arg = self.lookup(ref, kind, scope)
        actual = self.arg_kind(arg)
        if not _compatible(actual, kind):
            raise VfError(f"expected {describe_kind(kind)}, but '{ref.name}' is {describe_kind(actual)}",
                          ref.span, code="E203")
        return arg

    def lookup(self, ref: ast.NameRef, kind: str, scope: fx.Scope) -> ir.Arg:
        """The argument a name stands for in ``scope`` (``kind``: what is expected, for messages)."""
        if scope.bindings is not None:
            if ref.name not in scope.bindings:
                raise VfError(f"unknown name '{ref.name}' in fixture '{scope.fixture}'", ref.span,
                              hint=suggest(ref.name, scope.bindings, "formals") +
                              " (a fixture body sees only its formals)", code="E201")
            arg = scope.bindings[ref.name]
        elif ref.name in self.frames:
            arg = ir.FrameRef(name=ref.name)
        elif ref.name in self.inputs:
            arg = ir.InputRef(name=ref.name)
        elif ref.name in self.params:
            arg = ir.ParamRef(name=ref.name)
        elif ref.name in self.captures:
            if not scope.captures:
                raise VfError(f"'{ref.name}' is captured on entry to a phase; a statement outside every phase holds "
                              "in every phase, before any capture", ref.span,
                              hint=f"move the statement into the phase that needs it ({self.captures[ref.name].span} "
                                   "captures it)", code="E810")
            arg = ir.CaptureRef(name=ref.name)
        elif ref.name in self.robots:
            raise VfError(f"'{ref.name}' is a robot; expected {describe_kind(kind)}", ref.span, code="E203")
        elif ref.name in self.failed:
            raise Dependent
        else:
            raise non_finite_name(ref.name, ref.span) or VfError(
                f"unknown {kind.replace('_', ' ')} '{ref.name}'", ref.span,
                hint=suggest(ref.name, self._names_of(kind, scope), f"{kind.replace('_', ' ')}s"), code="E201")
        return arg

    def _scoped_reader(self, scope: fx.Scope) -> LiteralReader:
        """Reads literals in ``scope``'s units; names inside them must stand for constants."""
        return LiteralReader(scope.units, lambda ref, k: self._constant(ref, k, scope))

    def _constant(self, ref: ast.NameRef, kind: str, scope: fx.Scope) -> ir.Value:
        """A name inside a composite literal or a clause: it must stand for a compile-time constant."""
        arg = self._resolve_name(ref, kind, scope)
        if not isinstance(arg, ir.Const):
            raise VfError(f"'{ref.name}' is a run-time {kind}; only constants can stand here", ref.span,
                          hint="write the value itself here (or pass a literal into the fixture)", code="E206")
        return arg.value

    def arg_kind(self, arg: ir.Arg) -> str:
        if isinstance(arg, ir.FrameRef):
            return "frame"
        if isinstance(arg, ir.InputRef):
            return "input"
        if isinstance(arg, ir.ParamRef):
            return self.params[arg.name].type
        if isinstance(arg, ir.CaptureRef):
            return self.captures[arg.name].kind
        if isinstance(arg, ir.Derived):
            return arg.kind
        value = arg.value
        return value.dimension if isinstance(value, ir.ScalarValue) else value.kind

    # ------------------------------------------------------------------------------- statements
    def _bind(self, call: ast.Call, specs: tuple[ArgSpec, ...], scope: fx.Scope, what: str,
              subject: ir.FrameRef | None = None) -> tuple[dict[str, ir.Arg], dict[str, ast.Span]]:
        """The arguments and where each given one was written. Every argument checked on its own; a gain not when its
        input failed (its unit depends on the input)."""
        given = bind_arguments(call, [s.name for s in specs], {s.name for s in specs if s.required}, what)
        spans = {name: scope.source_span(value) for name, value in given.items()}
        args: dict[str, ir.Arg] = {}
        input_type, input_failed = None, False
        checks = []
        for spec in specs:
            if spec.name in given:
                with self.errors.each(scope.note) as check:
                    if spec.kind in ("gain", "angular_gain") and input_failed:
                        raise Dependent
                    args[spec.name] = (_choice(given[spec.name], spec, what) if spec.kind == "choice" else
                                       self.evaluate(given[spec.name], spec.kind, scope, input_type))
                    if isinstance(args[spec.name], ir.InputRef):
                        input_type = self.inputs[args[spec.name].name].type
                    if spec.range is not None:
                        self._check_range(spec, args[spec.name], spans[spec.name], call, scope)
                checks.append(check)
                input_failed = input_failed or (spec.kind == "input" and check.failed)
            elif spec.default == "subject":
                args[spec.name] = subject
            elif spec.default is not None:
                args[spec.name] = ir.Const(value=spec.default)
        self.errors.settle(*checks)
        return args, spans

    def _check_range(self, spec: ArgSpec, arg: ir.Arg, written: ast.Span, call: ast.Call, scope: fx.Scope) -> None:
        """A scalar argument (a literal, or a param's value) must lie in its spec's range."""
        what = f"{call.name.text}(...) argument '{spec.name}'"
        dim = SCALAR_DIMENSIONS.get(spec.kind)

        def shown(value: float, units: u.DefaultUnits) -> str:
            return units.show(value, dim) if dim is not None else f"{value:g} (SI units)"
        if isinstance(arg, ir.Const) and isinstance(arg.value, ir.ScalarValue):
            problem = spec.range.violation(arg.value.value)
            if problem:
                raise VfError(f"{what} {problem}, got {shown(arg.value.value, scope.units)}", written,
                              hint=f"{spec.name} is {spec.doc}; allowed: {spec.range.describe()}", code="E402")
        elif isinstance(arg, ir.ParamRef) and isinstance(self.params[arg.name].value, ir.ScalarValue):
            value = self.params[arg.name].value.value
            problem = spec.range.violation(value)
            if problem:
                raise VfError(f"param '{arg.name}' is used as {what}, which {problem}; its value is "
                              f"{shown(value, self.units)}", self.param_values[arg.name].span,
                              hint=f"{spec.name} is {spec.doc}; allowed: {spec.range.describe()}",
                              notes=(f"used at {written}",), code="E402")

    def _objective(self, stmt: ast.MinimizeStmt, scope: fx.Scope) -> ir.Objective:
        name = stmt.call.name
        spec = _lookup_spec(name, OBJECTIVES, "objective term", CONSTRAINTS,
                            f"'{name.text}' is a constraint: write `require <frame> {name.text}(...)`")
        clauses = stmt.clauses
        with self.errors.each(scope.note) as form:
            for clause, word in ((clauses.within, "within"), (clauses.resolution, "resolution"),
                                 (clauses.soft, "soft")):
                if clause is not None:
                    raise VfError(f"`{word}` applies to constraints, not to objective terms", _span(clause),
                                  code="E502")
        with self.errors.each(scope.note) as bound:
            args, spans = self._bind(stmt.call, spec.args, scope, f"{name.text}(...)")
            if name.text == "track":
                self._check_track(stmt.call, args)
            elif name.text == "teleop":
                self._check_teleop(stmt.call, args)
        with self.errors.each(scope.note) as weighed:
            weight = self._weight(clauses.weight, scope, 1.0)
        with self.errors.each(scope.note) as levelled:
            priority = self._priority(clauses.priority, scope, spec.priority)
        self.errors.settle(form, bound, weighed, levelled)
        return ir.Objective(term=name.text, args=args, weight=weight, priority=priority, span=stmt.span,
                            via=list(scope.via), arg_spans=spans)

    def _priority(self, value: ast.Value | None, scope: fx.Scope, default: int) -> int:
        if value is None:
            return default
        level = self._scoped_reader(scope).integer(value, "a priority")
        if level > limits.PRIORITY_LEVELS:
            raise limits.exceeded(f"priority {level} is too low a level", limits.PRIORITY_LEVELS,
                                  scope.source_span(value),
                                  hint="1 is solved first; each level is one more solve per tick", code="E701")
        return level

    def _check_track(self, call: ast.Call, args: dict[str, ir.Arg]) -> None:
        """Gains the input needs, and something left to track."""
        if not (flag(args, "linear") or flag(args, "angular")):
            raise VfError("track with `linear = false` and `angular = false` tracks nothing", call.span,
                          hint="leave one part tracked, or remove the term", code="E503")
        input_type = self.inputs[args["input"].name].type
        if not INPUT_TYPES[input_type].moves:
            raise VfError(f"track needs an input that commands a motion; '{args['input'].name}' is a {input_type}",
                          call.span, hint=f"track reads {described(lambda t: t.moves)}; a {input_type} is read by "
                                          f"{_reader(input_type)}", code="E503")
        default = INPUT_TYPES[input_type].default_gain
        for kind in ("gain", "angular_gain"):
            if gain_dimension(input_type, kind) is not None and kind not in args:
                if default is not None:
                    args[kind] = ir.Const(value=ir.ScalarValue(dimension=kind, value=default))
                else:
                    example = "gain = 2 mm/s/N" if kind == "gain" else "angular_gain = 5 deg/s/Nm"
                    raise VfError(f"track with a {input_type} input needs {kind}", call.span,
                                  hint=f"e.g. {example}", code="E503")

    def _check_teleop(self, call: ast.Call, args: dict[str, ir.Arg]) -> None:
        """The master is a pose input."""
        input_type = self.inputs[args["master"].name].type
        if input_type != "pose":
            raise VfError(f"teleop follows a master's pose; '{args['master'].name}' is a {input_type}", call.span,
                          hint=f"declare the master as `input {args['master'].name} : pose`; a {input_type} is read "
                               f"by {_reader(input_type)}", code="E503")

    def _constraint(self, stmt: ast.RequireStmt, scope: fx.Scope) -> ir.Constraint:
        name = stmt.call.name
        spec = _lookup_spec(name, CONSTRAINTS, "primitive", OBJECTIVES,
                            f"'{name.text}' is an objective term: write `minimize {name.text}(...)`")
        clauses = stmt.clauses
        subject = None
        with self.errors.each(scope.note) as subjected:
            subject = self._subject(stmt, spec, scope)
        with self.errors.each(scope.note) as bound:
            args, spans = self._bind(stmt.call, spec.args, scope, f"{name.text}(...)", subject)
        with self.errors.each(scope.note) as tolerated:
            tolerance = self._tolerance(clauses.within, spec, scope)
        with self.errors.each(scope.note) as resolved:
            self.errors.settle(bound)                # the polytope's shape may depend on the arguments
            shape = spec.resolution_shape(args)
            if shape is None and clauses.resolution is not None:
                raise VfError(f"{name.text} takes no polytope resolution", clauses.resolution.span, code="E502")
            resolution = None if shape is None else self._resolution(clauses.resolution, shape, spec)
        with self.errors.each(scope.note) as softened:
            for clause, word in ((clauses.weight, "weight"), (clauses.priority, "priority")):
                if clause is not None and clauses.soft is None:
                    raise VfError(f"`{word}` applies to soft constraints", clause.span,
                                  hint=f"add `soft` to make this constraint soft; hard constraints have no {word}: "
                                       "they always hold", code="E502")
            soft = clauses.soft is not None
            weight = self._weight(clauses.weight, scope, DEFAULT_SOFT_WEIGHT) if soft else None
            priority = self._priority(clauses.priority, scope, TASK_LEVEL) if soft else None
        self.errors.settle(subjected, bound, tolerated, resolved, softened)
        return ir.Constraint(primitive=name.text, frame=subject.name if subject else None, args=args,
                             tolerance=tolerance, resolution=resolution, soft=soft, weight=weight,
                             priority=priority, span=stmt.span, via=list(scope.via), arg_spans=spans)

    def _subject(self, stmt: ast.RequireStmt, spec, scope: fx.Scope) -> ir.FrameRef | None:
        """The task frame a constraint applies to (None for a whole-robot constraint)."""
        name = stmt.call.name
        if spec.subject:
            if stmt.subject is None:
                raise VfError(f"{name.text} applies to a task frame", name.span,
                              hint=f"write `require <frame> {name.text}(...)`", code="E503")
            return self.evaluate(ast.NameRef(span=stmt.subject.span, name=stmt.subject.text), "frame", scope)
        if stmt.subject is not None:
            raise VfError(f"{name.text} applies to the whole robot, not to a frame", stmt.subject.span,
                          hint=f"write `require {name.text}(...)`", code="E503")
        return None

    def _tolerance(self, within: ast.Value | None, spec, scope: fx.Scope) -> float | None:
        """A constraint's ``within`` (SI), or its primitive's default; None for a primitive without one."""
        if spec.tolerance is None:
            if within is not None:
                raise VfError(f"{spec.name} takes no tolerance (`within`)", within.span, code="E502")
            return None
        if within is None:
            return spec.default_tolerance
        tolerance = self._scoped_reader(scope).scalar(within, SCALAR_DIMENSIONS[spec.tolerance], spec.tolerance)
        self._check_tolerance(tolerance, spec.tolerance, scope.source_span(within), scope.units)
        return tolerance

    def _check_tolerance(self, tolerance: float, kind: str, written: ast.Span, units: u.DefaultUnits) -> None:
        """A ``within`` value must be positive and large enough for the solver to honour it."""
        if tolerance <= 0:
            raise VfError("a tolerance must be positive", written, code="E402")
        allowed = clause_ranges.tolerance_range(kind)
        if allowed.violation(tolerance) is None:
            return
        unit = units.length if kind == "length" else units.angle
        scale = u.UNITS[unit][1]
        if tolerance < allowed.low:
            raise VfError(f"tolerance {tolerance / scale:g} {unit} is below what the solver can honour: it holds "
                          f"rows to {clause_ranges.FEASIBILITY_TOLERANCE / scale:g} {unit} (its feasibility tolerance; "
                          f"{clause_ranges.LEVELS_TOLERANCE / scale:g} {unit} with priority levels)",
                          written, hint=f"use at least {allowed.low / scale:g} {unit} "
                                              f"({clause_ranges.TOLERANCE_MARGIN} times the solver's tolerance)",
                          code="E402")
        if kind == "angle":
            raise VfError(f"an angle tolerance must be below 90 deg, got {math.degrees(tolerance):g} deg", written,
                          code="E402")
        raise VfError(f"tolerance {tolerance / scale:g} {unit} is beyond any robot's size: the limit is "
                      f"{allowed.high / scale:g} {unit} ({allowed.high:g} m)", written,
                      hint="a unit slip? give the unit, e.g. `within 0.5 mm`", code="E402")

    def _resolution(self, given: ast.Resolution | None, shape: str, spec) -> list[int]:
        if given is None:
            return list(spec.default_resolution[shape])
        counts = given.counts
        if shape == "sphere" and len(counts) != 2:
            raise VfError(f"{spec.name} is bounded by a sphere polytope: give n x m directions", given.span,
                          hint="e.g. resolution 4x4", code="E401")
        if shape == "polygon" and len(counts) != 1:
            raise VfError(f"{spec.name} is bounded by a polygon: give its number of sides", given.span,
                          hint="e.g. resolution 8", code="E401")
        if min(counts) < 3:
            raise VfError("a bounded polytope needs at least 3 directions per angle", given.span,
                          hint="use 3 or more (the paper uses 4x4 for a sphere and 8 for a polygon)", code="E402")
        if max(counts) > limits.RESOLUTION:
            raise limits.exceeded(f"resolution {max(counts)} is too fine", limits.RESOLUTION, given.span,
                                  hint="directions per angle of a polytope; the paper uses 4x4 and 8", code="E701")
        return counts

    def _weight(self, value: ast.Value | None, scope: fx.Scope, default: float) -> float:
        if value is None:
            return default
        reader = self._scoped_reader(scope)
        weight = reader.scalar(value, u.DIMENSIONLESS, "number")
        problem = clause_ranges.WEIGHT.violation(weight)
        if problem:
            raise VfError(f"a weight {problem}, got {weight:g}", scope.source_span(value),
                          hint=f"a weight is a plain number in {clause_ranges.WEIGHT.describe()}, e.g. 10 or 1e-6",
                          code="E402")
        return weight


def _lookup_spec(name: ast.Name, table: dict, what: str, other: dict, other_hint: str):
    """The signature called ``name`` in ``table``; a helpful error when it is unknown or in ``other``."""
    if name.text in table:
        return table[name.text]
    hint = other_hint if name.text in other else suggest(name.text, table, f"{what}s")
    raise VfError(f"unknown {what} '{name.text}'", name.span, hint=hint, code="E205")


def _reader(input_type: str) -> str:
    """What reads an input of this type: track (a motion), monitors (a button), teleop (a pose)."""
    if INPUT_TYPES[input_type].moves:
        return "track"
    if INPUT_TYPES[input_type].switch:
        return "monitors"
    return "teleop (a master's pose)" if input_type == "pose" else "no term yet (a set-point, not a rate)"


def _compatible(actual: str, expected: str) -> bool:
    return actual == expected or (expected == "vector" and actual == "point")


def _row_estimate(c: ir.Constraint) -> int:
    """At most how many rows ``c`` adds (its polytope's directions, or 2 for a two-sided row)."""
    return math.prod(c.resolution) if c.resolution else 2


def _span(clause) -> ast.Span:
    return clause if isinstance(clause, ast.Span) else clause.span


def resolve(module: ast.Module, path: Path, libraries: list[tuple[ast.Module, u.DefaultUnits]],
            imports: list[str]) -> ir.Task:
    return Resolver(module, path, libraries).run(imports)


def _choice(value: ast.Value, spec: ArgSpec, what: str) -> ir.Const:
    """A ``choice`` argument: one of the words its spec allows, written as a bare name (rotation = relative)."""
    if not isinstance(value, ast.NameRef) or value.name not in spec.choices:
        written = f"'{value.name}'" if isinstance(value, ast.NameRef) else "a value"
        raise VfError(f"{what} argument '{spec.name}' is one of {', '.join(spec.choices)}; got {written}", value.span,
                      hint=suggest(value.name if isinstance(value, ast.NameRef) else "", spec.choices, "choices"),
                      code="E401")
    return ir.Const(value=ir.ChoiceValue(value=value.name))
