"""Name resolution and checking: syntax tree (+ scene, + libraries) -> the checked :class:`~vfdsl.ir.model.Task`.

The pass walks the task's declarations in order (one namespace for robots, frames, inputs and params;
a name may be declared once), expands fixtures, then checks every ``require``/``minimize`` call against its
primitive's signature (:mod:`vfdsl.primitives.spec`): argument names and kinds, units (via
:mod:`vfdsl.units`), shapes (via :mod:`vfdsl.passes.shapes`) and the argument's allowed range (for a
literal, at the literal; for a param, at the param's value and naming the use), then the clauses ``within``,
``resolution``, ``soft`` and ``weight`` against :mod:`vfdsl.limits`. Any mistake raises
:class:`~vfdsl.errors.VfError` at its position.
"""

from __future__ import annotations

import math
from pathlib import Path

from vfdsl.compiler.admissible import Admissible
from vfdsl.compiler.geometry import compose, rotation
from vfdsl.errors import VfError, suggest
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import ROBOTS_DIR, Robot
from vfdsl.objectives import OBJECTIVES
from vfdsl.passes import clause_ranges
from vfdsl.passes import expressions as ex
from vfdsl.passes import fixtures as fx
from vfdsl import limits
from vfdsl import units as u
from vfdsl.passes.calls import bind_arguments
from vfdsl.passes.scene import SceneData, load_scene
from vfdsl.passes.shapes import LiteralReader, describe_kind
from vfdsl.primitives import CONSTRAINTS
from vfdsl.primitives.spec import (
    GEOMETRIC_KINDS,
    SCALAR_DIMENSIONS,
    TASK_LEVEL,
    ArgSpec,
    flag,
    gain_dimension,
)
from vfdsl.syntax import ast

PARAM_KINDS = GEOMETRIC_KINDS + tuple(SCALAR_DIMENSIONS)
DEFAULT_SOFT_WEIGHT = 1.0
_AXES = {"x": [1.0, 0.0, 0.0], "y": [0.0, 1.0, 0.0], "z": [0.0, 0.0, 1.0]}


def file_units(module: ast.Module) -> u.DefaultUnits:
    """The defaults set by a file's (single) ``units`` statement."""
    statements = [s for s in module.statements if isinstance(s, ast.UnitsStmt)]
    if len(statements) > 1:
        raise VfError("only one `units` statement per file", statements[1].span.pos(),
                      hint=f"the first is at {statements[0].span}")
    if not statements:
        return u.DefaultUnits()
    return u.default_units([(name.text, name.span) for name in statements[0].names])


class Resolver:
    """Builds the IR of one task. Use :func:`resolve`."""

    def __init__(self, module: ast.Module, path: Path, libraries: list[tuple[ast.Module, u.DefaultUnits]]):
        self.module = module
        self.path = path
        self.units = file_units(module)
        self.fixtures = fx.collect(libraries + [(module, self.units)])
        self.declared: dict[str, ast.Node] = {}            # name -> its declaring statement
        self.robots: dict[str, tuple[ir.RobotDecl, Robot]] = {}
        self.frames: dict[str, ir.FrameDecl] = {}
        self.inputs: dict[str, ir.InputDecl] = {}
        self.params: dict[str, ir.ParamDecl] = {}
        self.param_values: dict[str, ast.Value] = {}        # param -> the literal its value was read from
        self.task_scope = fx.Scope(units=self.units)

    # ----------------------------------------------------------------------------------- entry point
    def run(self, imports: list[str]) -> ir.Task:
        statements = self.module.statements
        scene = self._scene(statements)
        for stmt in statements:
            if isinstance(stmt, (ast.RobotStmt, ast.FrameStmt, ast.InputStmt, ast.ParamStmt)):
                self._declare(stmt.name)
        for stmt in statements:
            if isinstance(stmt, ast.RobotStmt):
                self._robot(stmt)
        if not self.robots:
            raise VfError("a task drives exactly one robot; none is declared", self.module.name.span.pos(),
                          hint='declare it with: robot shr = urdf "shr7"')
        if len(self.robots) > 1:
            first, second = (decl.span for decl, _ in list(self.robots.values())[:2])
            raise VfError("a task drives exactly one robot", second.pos(),
                          hint=f"the first is declared at {first}; split the task, one per robot")
        for stmt in statements:
            if isinstance(stmt, ast.FrameStmt):
                self._frame(stmt)
            elif isinstance(stmt, ast.InputStmt):
                self._input(stmt)
        self._params([s for s in statements if isinstance(s, ast.ParamStmt)], scene)
        body = [s for s in statements if isinstance(s, (ast.MinimizeStmt, ast.RequireStmt, ast.UseStmt))]
        objectives, constraints = [], []
        rows = 0
        for stmt, scope in fx.expand(body, self.task_scope, self.fixtures, self.evaluate):
            try:
                if isinstance(stmt, ast.MinimizeStmt):
                    objectives.append(self._objective(stmt, scope))
                    continue
                constraints.append(self._constraint(stmt, scope))
                if len(constraints) > limits.CONSTRAINTS:
                    raise limits.exceeded("too many constraints", limits.CONSTRAINTS, stmt.span.pos())
                rows += _row_estimate(constraints[-1])
                if rows > limits.ROWS:
                    raise limits.exceeded(f"too many constraint rows (about {rows:,} so far)", limits.ROWS,
                                          stmt.span.pos(), hint="lower the resolution of the polytopes")
            except VfError as error:
                raise scope.note(error) from None
        robot_decl, robot = next(iter(self.robots.values()))
        task = ir.Task(
            name=self.module.name.text, file=str(self.path), span=self.module.span,
            robots=[robot_decl], frames=list(self.frames.values()), inputs=list(self.inputs.values()),
            params=list(self.params.values()), objectives=objectives, constraints=constraints,
            scene=self._scene_ir(scene, robot), imports=imports)
        self._check_param_values(task, robot)
        return task

    def _check_param_values(self, task: ir.Task, robot: Robot) -> None:
        """The params' values (the task's defaults, or the scene's) pass the checks a run-time value gets
        (:mod:`vfdsl.compiler.admissible`); an error points at the value, in the task or the scene file."""
        admissible = Admissible(task, robot.reach)
        p = admissible.layout.defaults
        numbers = admissible.function(p)
        i = admissible.margins.first_failure(numbers)
        if i < 0:
            return
        error = admissible.margins.error(i, numbers, p, "with the params' values, ")
        name = admissible.margins.checks[i].param
        if name is not None:
            error = VfError(error.message, self.param_values[name].span.pos(), error.hint,
                            notes=(f"param '{name}' is declared at {self.params[name].span}",))
        raise error

    # ---------------------------------------------------------------------------------- declarations
    def _declare(self, name: ast.Name) -> None:
        if name.text in self.declared:
            raise VfError(f"'{name.text}' is declared twice", name.span.pos(),
                          hint=f"first declared at {self.declared[name.text].span}")
        self.declared[name.text] = name

    def _robot(self, stmt: ast.RobotStmt) -> None:
        try:
            robot = Robot.load(stmt.urdf, base_dir=self.path.parent)
        except VfError as exc:
            raise VfError(exc.message, stmt.span.pos(), exc.hint) from None
        shipped = robot.urdf_path.parent == ROBOTS_DIR
        decl = ir.RobotDecl(name=stmt.name.text, urdf=robot.name if shipped else str(robot.urdf_path), span=stmt.span)
        self.robots[stmt.name.text] = (decl, robot)

    def _frame(self, stmt: ast.FrameStmt) -> None:
        """A frame on a robot link, or on an earlier frame (composed: the base's link, offset and rotation,
        then this frame's; the tool axis is the base's, in the new frame's coordinates, unless given)."""
        if stmt.base is not None:
            base = self._base_frame(stmt)
            robot_name, link = base.robot, base.link
            robot = self.robots[robot_name][1]
        else:
            if stmt.robot.text not in self.robots:
                hint = (f"'{stmt.robot.text}' is a frame; a frame on it is written `frame {stmt.name.text} = "
                        f"{stmt.robot.text} offset [...]`" if self._is_frame_statement(stmt.robot.text)
                        else suggest(stmt.robot.text, self.robots, "robots"))
                raise VfError(f"unknown robot '{stmt.robot.text}'", stmt.robot.span.pos(), hint=hint)
            robot_name, link, robot = stmt.robot.text, stmt.link.text, self.robots[stmt.robot.text][1]
            if link not in robot.link_names():
                raise VfError(f"robot '{robot_name}' has no link '{link}'", stmt.link.span.pos(),
                              hint=suggest(link, robot.link_names(), "links"))
        offset = self._literal(stmt.offset, "vector", self.units).xyz if stmt.offset else [0.0, 0.0, 0.0]
        rpy = self._literal(stmt.rotate, "rpy", self.units).xyz if stmt.rotate else [0.0, 0.0, 0.0]
        if stmt.axis is not None:
            axis = (_AXES[stmt.axis.name] if isinstance(stmt.axis, ast.NameRef) and stmt.axis.name in _AXES
                    else self._literal(stmt.axis, "direction", self.units).xyz)
        elif stmt.base is not None:
            axis = (rotation(rpy).T @ base.tool_axis).tolist()
        else:
            axis = _AXES[robot.tool_axis.get(link, "z")]
        if stmt.base is not None:
            offset, rpy = compose(base.offset, base.rpy, offset, rpy)
            if not all(map(math.isfinite, offset)):
                raise VfError(f"frame '{stmt.name.text}' is too far from its link: its offset composed with frame "
                              f"'{base.name}''s overflows", stmt.span.pos())
        distance = math.hypot(*offset)
        if distance > limits.LENGTH:
            raise limits.exceeded(f"frame '{stmt.name.text}' is {distance:g} m from its link", limits.LENGTH,
                                  (stmt.offset.span if stmt.offset is not None else stmt.span).pos(),
                                  hint="is the unit right? (bare numbers take the file's `units`)", unit="m")
        self.frames[stmt.name.text] = ir.FrameDecl(name=stmt.name.text, robot=robot_name, link=link,
                                                   offset=offset, rpy=rpy, tool_axis=axis, span=stmt.span,
                                                   base=stmt.base.text if stmt.base is not None else None)

    def _base_frame(self, stmt: ast.FrameStmt) -> ir.FrameDecl:
        name = stmt.base.text
        if name in self.frames:
            return self.frames[name]
        where = stmt.base.span.pos()
        if name == stmt.name.text:
            raise VfError(f"frame '{name}' is defined from itself", where,
                          hint=f"build it on a robot link: frame {name} = <robot>.link(\"...\")")
        if self._is_frame_statement(name):
            raise VfError(f"frame '{name}' is declared later (line {self.declared[name].span.line}); a frame can "
                          f"only be built on a frame declared before it", where,
                          hint=f"move frame '{name}' above this line")
        if name in self.robots:
            raise VfError(f"'{name}' is a robot, not a frame", where,
                          hint=f'a frame on one of its links is written: frame {stmt.name.text} = {name}.link("...")')
        if name in self.declared:
            raise VfError(f"'{name}' is not a frame", where, hint=suggest(name, self.frames, "frames"))
        raise VfError(f"unknown frame '{name}'", where, hint=suggest(name, self.frames, "frames"))

    def _is_frame_statement(self, name: str) -> bool:
        return any(isinstance(s, ast.FrameStmt) and s.name.text == name for s in self.module.statements)

    def _literal(self, value: ast.Value, kind: str, units: u.DefaultUnits,
                 curve_degree: int | None = None) -> ir.Value:
        """A value without names (a param's value, a frame clause): a literal, or an expression of literals."""
        if kind in ex.KINDS and ex.is_expression(value):
            return ex.Expressions(units, lambda ref: self._no_names(ref, kind), self._arg_kind, []) \
                .evaluate(value, kind).value
        return LiteralReader(units, self._no_names).read(value, kind, curve_degree=curve_degree)

    def _input(self, stmt: ast.InputStmt) -> None:
        if stmt.type.text not in ir.INPUT_SIZES:
            raise VfError(f"unknown input type '{stmt.type.text}'", stmt.type.span.pos(),
                          hint=suggest(stmt.type.text, ir.INPUT_SIZES, "input types"))
        self.inputs[stmt.name.text] = ir.InputDecl(name=stmt.name.text, type=stmt.type.text, span=stmt.span)

    def _params(self, statements: list[ast.ParamStmt], scene: SceneData | None) -> None:
        by_name = {s.name.text: s for s in statements}
        if scene is not None:
            for name, (_, key_span) in scene.params.items():
                if name not in by_name:
                    raise VfError(f"the scene sets '{name}', which is not a param of this task", key_span.pos(),
                                  hint=suggest(name, by_name, "params"))
        for stmt in statements:
            kind = stmt.type.text
            if kind not in PARAM_KINDS:
                raise VfError(f"unknown param type '{kind}'", stmt.type.span.pos(),
                              hint=suggest(kind, PARAM_KINDS, "param types"))
            degree, runtime = self._curve_type(stmt)
            if stmt.frame is not None:
                target = by_name.get(stmt.frame.text)
                if target is None or target.type.text != "pose":
                    poses = [s.name.text for s in statements if s.type.text == "pose"]
                    raise VfError(f"'{stmt.frame.text}' is not a pose param", stmt.frame.span.pos(),
                                  hint=suggest(stmt.frame.text, poses, "pose params"))
                if kind == "pose":
                    raise VfError("a pose cannot be expressed `in` another pose", stmt.frame.span.pos(),
                                  hint="nested frames are not supported: give the pose in the robot's base frame")
                if kind not in ("point", "vector", "direction", "line", "plane", "curve"):
                    raise VfError(f"a {kind} cannot be expressed in a frame", stmt.frame.span.pos())
            if scene is not None and stmt.name.text in scene.params:
                source, units = scene.params[stmt.name.text][0], scene.units
            elif stmt.default is not None:
                source, units = stmt.default, self.units
            else:
                raise VfError(f"param '{stmt.name.text}' has no value", stmt.name.span.pos(),
                              hint=f"give a default (`= ...`) or set params.{stmt.name.text} in the scene file")
            source = _named_mapping(source, kind)
            self.param_values[stmt.name.text] = source
            value = self._literal(source, kind, units, degree)
            if runtime:
                value = value.model_copy(update={"runtime": True})
            self.params[stmt.name.text] = ir.ParamDecl(
                name=stmt.name.text, type=kind, value=value,
                frame=stmt.frame.text if stmt.frame else None, span=stmt.span)

    def _curve_type(self, stmt: ast.ParamStmt) -> tuple[int | None, bool]:
        """(degree, runtime) of a curve param's type, e.g. curve(degree = 1, runtime = true)."""
        if stmt.type.text != "curve":
            if stmt.type_args:
                raise VfError(f"a {stmt.type.text} param takes no type arguments", stmt.type_args[0].span.pos())
            return None, False
        degree, runtime = None, False
        reader = LiteralReader(self.units, self._no_names)
        for kw in stmt.type_args:
            if kw.name.text == "degree":
                degree = reader.integer(kw.value, "degree")
            elif kw.name.text == "runtime":
                runtime = reader.read(kw.value, "flag").value
            else:
                raise VfError(f"curve has no type argument '{kw.name.text}'", kw.name.span.pos(),
                              hint="write curve(degree = 5), or curve(degree = 1, runtime = true)")
        return degree, runtime

    # ---------------------------------------------------------------------------------------- scene
    def _scene(self, statements) -> SceneData | None:
        explicit = [s for s in statements if isinstance(s, ast.SceneStmt)]
        if len(explicit) > 1:
            raise VfError("only one `scene` statement per task", explicit[1].span.pos())
        if explicit:
            return load_scene(self.path.parent / explicit[0].path, self.units, explicit[0].span.pos())
        default = self.path.with_suffix(".yaml")
        return load_scene(default, self.units, None) if default.is_file() else None

    def _scene_ir(self, scene: SceneData | None, robot: Robot) -> ir.Scene:
        if scene is None:
            return ir.Scene()
        reader = LiteralReader(scene.units, self._no_names)
        period = None
        if scene.period is not None:
            period = reader.scalar(scene.period, u.TIME, "period")
            if period <= 0:
                raise VfError("the period must be positive", scene.period.span.pos())
            if period < limits.MIN_PERIOD:
                raise limits.exceeded(f"a period of {period:g} s is too short", limits.MIN_PERIOD,
                                      scene.period.span.pos(), hint="the shortest control period is 10 us (100 kHz)",
                                      unit="s")
        start = None
        if scene.start is not None:
            start = self._start(scene.start, scene.start_span, reader, robot)
        return ir.Scene(file=str(scene.file), start=start, period=period)

    def _start(self, value, span: ast.Span, reader: LiteralReader, robot: Robot) -> list[float]:
        dims = [u.LENGTH if t == "prismatic" else u.ANGLE for t in robot.joint_types]
        if isinstance(value, dict):
            for name, (_, key_span) in value.items():
                if name not in robot.joint_names:
                    raise VfError(f"robot '{robot.name}' has no joint '{name}'", key_span.pos(),
                                  hint=suggest(name, robot.joint_names, "joints"))
            missing = [n for n in robot.joint_names if n not in value]
            if missing:
                raise VfError(f"the start configuration misses joint{'s' if len(missing) > 1 else ''} "
                              f"{', '.join(missing)}", span.pos(), hint="give a value for every joint")
            values = [value[n][0] for n in robot.joint_names]
        else:
            if not isinstance(value, ast.Vector) or len(value.items) != robot.nq:
                raise VfError(f"the start configuration needs {robot.nq} joint values "
                              f"({', '.join(robot.joint_names)})", span.pos())
            values = value.items
        q = [reader.scalar(v, d, "joint value") for v, d in zip(values, dims)]
        for name, x, lo, hi, v in zip(robot.joint_names, q, robot.lower, robot.upper, values):
            if not lo - 1e-12 <= x <= hi + 1e-12:
                raise VfError(f"joint {name} starts outside its limits [{lo:g}, {hi:g}] (SI units)", v.span.pos())
        return q

    # ------------------------------------------------------------------------------------- names
    def _no_names(self, ref: ast.NameRef, kind: str) -> ir.Value:
        raise VfError(f"a name ('{ref.name}') cannot stand here; write the value itself", ref.span.pos())

    def evaluate(self, value: ast.Value, kind: str, scope: fx.Scope, input_type: str | None = None) -> ir.Arg:
        """The IR argument for ``value`` read as ``kind`` in ``scope`` (names resolve lexically)."""
        if isinstance(value, ast.NameRef):
            return self._resolve_name(value, kind, scope)
        if kind in ("frame", "input"):
            raise VfError(f"expected the name of {describe_kind(kind)}", value.span.pos(),
                          hint=suggest("", self._names_of(kind, scope), f"{kind}s"))
        if kind in ex.KINDS and ex.is_expression(value):
            return ex.Expressions(scope.units, lambda ref: self._lookup(ref, "name", scope), self._arg_kind,
                                  list(self.params.values())).evaluate(value, kind)
        reader = self._scoped_reader(scope)
        if kind in ("gain", "angular_gain"):
            dim = gain_dimension(input_type, kind)
            if dim is None:
                raise VfError(f"a {input_type} input has no {kind.replace('_', ' ')}", value.span.pos(),
                              hint="a force drives translation (gain), a torque drives rotation (angular_gain)")
            return ir.Const(value=ir.ScalarValue(dimension=kind, value=reader.scalar(value, dim, kind)))
        return ir.Const(value=reader.read(value, kind))

    def _names_of(self, kind: str, scope: fx.Scope) -> list[str]:
        if scope.bindings is not None:
            return list(scope.bindings)
        table = {"frame": self.frames, "input": self.inputs}.get(kind)
        if table is not None:
            return list(table)
        return [n for n, p in self.params.items() if p.type == kind] or list(self.params)

    def _resolve_name(self, ref: ast.NameRef, kind: str, scope: fx.Scope) -> ir.Arg:
        arg = self._lookup(ref, kind, scope)
        actual = self._arg_kind(arg)
        if not _compatible(actual, kind):
            raise VfError(f"expected {describe_kind(kind)}, but '{ref.name}' is {describe_kind(actual)}",
                          ref.span.pos())
        return arg

    def _lookup(self, ref: ast.NameRef, kind: str, scope: fx.Scope) -> ir.Arg:
        """The argument a name stands for in ``scope`` (``kind``: what is expected, for messages)."""
        if scope.bindings is not None:
            if ref.name not in scope.bindings:
                raise VfError(f"unknown name '{ref.name}' in fixture '{scope.fixture}'", ref.span.pos(),
                              hint=suggest(ref.name, scope.bindings, "formals") +
                              " (a fixture body sees only its formals)")
            arg = scope.bindings[ref.name]
        elif ref.name in self.frames:
            arg = ir.FrameRef(name=ref.name)
        elif ref.name in self.inputs:
            arg = ir.InputRef(name=ref.name)
        elif ref.name in self.params:
            arg = ir.ParamRef(name=ref.name)
        elif ref.name in self.robots:
            raise VfError(f"'{ref.name}' is a robot; expected {describe_kind(kind)}", ref.span.pos())
        else:
            raise VfError(f"unknown {kind.replace('_', ' ')} '{ref.name}'", ref.span.pos(),
                          hint=suggest(ref.name, self._names_of(kind, scope), f"{kind.replace('_', ' ')}s"))
        return arg

    def _scoped_reader(self, scope: fx.Scope) -> LiteralReader:
        """Reads literals in ``scope``'s units; names inside them must stand for constants."""
        return LiteralReader(scope.units, lambda ref, k: self._constant(ref, k, scope))

    def _constant(self, ref: ast.NameRef, kind: str, scope: fx.Scope) -> ir.Value:
        """A name inside a composite literal or a clause: it must stand for a compile-time constant."""
        arg = self._resolve_name(ref, kind, scope)
        if not isinstance(arg, ir.Const):
            raise VfError(f"'{ref.name}' is a run-time {kind}; only constants can stand here", ref.span.pos(),
                          hint="write the value itself here (or pass a literal into the fixture)")
        return arg.value

    def _arg_kind(self, arg: ir.Arg) -> str:
        if isinstance(arg, ir.FrameRef):
            return "frame"
        if isinstance(arg, ir.InputRef):
            return "input"
        if isinstance(arg, ir.ParamRef):
            return self.params[arg.name].type
        if isinstance(arg, ir.Derived):
            return arg.kind
        value = arg.value
        return value.dimension if isinstance(value, ir.ScalarValue) else value.kind

    # ------------------------------------------------------------------------------- statements
    def _bind(self, call: ast.Call, specs: tuple[ArgSpec, ...], scope: fx.Scope, what: str,
              subject: ir.FrameRef | None = None) -> dict[str, ir.Arg]:
        given = bind_arguments(call, [s.name for s in specs], {s.name for s in specs if s.required}, what)
        args: dict[str, ir.Arg] = {}
        input_type = None
        for spec in specs:
            if spec.name in given:
                args[spec.name] = self.evaluate(given[spec.name], spec.kind, scope, input_type)
                if isinstance(args[spec.name], ir.InputRef):
                    input_type = self.inputs[args[spec.name].name].type
                if spec.range is not None:
                    self._check_range(spec, args[spec.name], scope.source_span(given[spec.name]), call, scope)
            elif spec.default == "subject":
                args[spec.name] = subject
            elif spec.default is not None:
                args[spec.name] = ir.Const(value=spec.default)
        return args

    def _check_range(self, spec: ArgSpec, arg: ir.Arg, written: ast.Span, call: ast.Call, scope: fx.Scope) -> None:
        """A scalar argument (a literal, or a param's value) must lie in its spec's range."""
        what = f"{call.name.text}(...) argument '{spec.name}'"
        dim = SCALAR_DIMENSIONS.get(spec.kind)

        def shown(value: float, units: u.DefaultUnits) -> str:
            return units.show(value, dim) if dim is not None else f"{value:g} (SI units)"
        if isinstance(arg, ir.Const) and isinstance(arg.value, ir.ScalarValue):
            problem = spec.range.violation(arg.value.value)
            if problem:
                raise VfError(f"{what} {problem}, got {shown(arg.value.value, scope.units)}", written.pos(),
                              hint=f"{spec.name} is {spec.doc}; allowed: {spec.range.describe()}")
        elif isinstance(arg, ir.ParamRef) and isinstance(self.params[arg.name].value, ir.ScalarValue):
            value = self.params[arg.name].value.value
            problem = spec.range.violation(value)
            if problem:
                raise VfError(f"param '{arg.name}' is used as {what}, which {problem}; its value is "
                              f"{shown(value, self.units)}", self.param_values[arg.name].span.pos(),
                              hint=f"{spec.name} is {spec.doc}; allowed: {spec.range.describe()}",
                              notes=(f"used at {written}",))

    def _objective(self, stmt: ast.MinimizeStmt, scope: fx.Scope) -> ir.Objective:
        name = stmt.call.name
        spec = _lookup_spec(name, OBJECTIVES, "objective term", CONSTRAINTS,
                            f"'{name.text}' is a constraint: write `require <frame> {name.text}(...)`")
        clauses = stmt.clauses
        for clause, word in ((clauses.within, "within"), (clauses.resolution, "resolution"), (clauses.soft, "soft")):
            if clause is not None:
                raise VfError(f"`{word}` applies to constraints, not to objective terms", _span(clause).pos())
        args = self._bind(stmt.call, spec.args, scope, f"{name.text}(...)")
        if name.text == "track":
            self._check_track(stmt.call, args)
        weight = self._weight(clauses.weight, scope, 1.0)
        priority = self._priority(clauses.priority, scope, spec.priority)
        return ir.Objective(term=name.text, args=args, weight=weight, priority=priority, span=stmt.span,
                            via=list(scope.via))

    def _priority(self, value: ast.Value | None, scope: fx.Scope, default: int) -> int:
        if value is None:
            return default
        level = self._scoped_reader(scope).integer(value, "a priority")
        if level > limits.PRIORITY_LEVELS:
            raise limits.exceeded(f"priority {level} is too low a level", limits.PRIORITY_LEVELS,
                                  scope.source_span(value).pos(),
                                  hint="1 is solved first; each level is one more solve per tick")
        return level

    def _check_track(self, call: ast.Call, args: dict[str, ir.Arg]) -> None:
        """Gains the input needs, and something left to track."""
        if not (flag(args, "linear") or flag(args, "angular")):
            raise VfError("track with `linear = false` and `angular = false` tracks nothing", call.span.pos(),
                          hint="leave one part tracked, or remove the term")
        input_type = self.inputs[args["input"].name].type
        for kind in ("gain", "angular_gain"):
            if gain_dimension(input_type, kind) is not None and kind not in args:
                if input_type == "twist":
                    args[kind] = ir.Const(value=ir.ScalarValue(dimension=kind, value=1.0))
                else:
                    example = "gain = 2 mm/s/N" if kind == "gain" else "angular_gain = 5 deg/s/Nm"
                    raise VfError(f"track with a {input_type} input needs {kind}", call.span.pos(),
                                  hint=f"e.g. {example}")

    def _constraint(self, stmt: ast.RequireStmt, scope: fx.Scope) -> ir.Constraint:
        name = stmt.call.name
        spec = _lookup_spec(name, CONSTRAINTS, "primitive", OBJECTIVES,
                            f"'{name.text}' is an objective term: write `minimize {name.text}(...)`")
        subject = None
        if spec.subject:
            if stmt.subject is None:
                raise VfError(f"{name.text} applies to a task frame", name.span.pos(),
                              hint=f"write `require <frame> {name.text}(...)`")
            subject = self.evaluate(ast.NameRef(span=stmt.subject.span, name=stmt.subject.text), "frame", scope)
        elif stmt.subject is not None:
            raise VfError(f"{name.text} applies to the whole robot, not to a frame", stmt.subject.span.pos(),
                          hint=f"write `require {name.text}(...)`")
        args = self._bind(stmt.call, spec.args, scope, f"{name.text}(...)", subject)
        clauses = stmt.clauses
        tolerance = None
        if spec.tolerance is None:
            if clauses.within is not None:
                raise VfError(f"{name.text} takes no tolerance (`within`)", clauses.within.span.pos())
        elif clauses.within is not None:
            reader = self._scoped_reader(scope)
            tolerance = reader.scalar(clauses.within, SCALAR_DIMENSIONS[spec.tolerance], spec.tolerance)
            self._check_tolerance(tolerance, spec.tolerance, scope.source_span(clauses.within), scope.units)
        else:
            tolerance = spec.default_tolerance
        shape = spec.resolution_shape(args)
        resolution = None
        if shape is None:
            if clauses.resolution is not None:
                raise VfError(f"{name.text} takes no polytope resolution", clauses.resolution.span.pos())
        else:
            resolution = self._resolution(clauses.resolution, shape, spec)
        for clause, word in ((clauses.weight, "weight"), (clauses.priority, "priority")):
            if clause is not None and clauses.soft is None:
                raise VfError(f"`{word}` applies to soft constraints", clause.span.pos(),
                              hint=f"add `soft` to make this constraint soft; hard constraints have no {word}: "
                                   "they always hold")
        soft = clauses.soft is not None
        weight = self._weight(clauses.weight, scope, DEFAULT_SOFT_WEIGHT) if soft else None
        priority = self._priority(clauses.priority, scope, TASK_LEVEL) if soft else None
        return ir.Constraint(primitive=name.text, frame=subject.name if subject else None, args=args,
                             tolerance=tolerance, resolution=resolution, soft=soft, weight=weight,
                             priority=priority, span=stmt.span, via=list(scope.via))

    def _check_tolerance(self, tolerance: float, kind: str, written: ast.Span, units: u.DefaultUnits) -> None:
        """A ``within`` value must be positive and large enough for the solver to honour it."""
        if tolerance <= 0:
            raise VfError("a tolerance must be positive", written.pos())
        allowed = clause_ranges.tolerance_range(kind)
        if allowed.violation(tolerance) is None:
            return
        unit = units.length if kind == "length" else units.angle
        scale = u.UNITS[unit][1]
        if tolerance < allowed.low:
            raise VfError(f"tolerance {tolerance / scale:g} {unit} is below what the solver can honour: it holds "
                          f"rows to {clause_ranges.FEASIBILITY_TOLERANCE / scale:g} {unit} (its feasibility tolerance)",
                          written.pos(), hint=f"use at least {allowed.low / scale:g} {unit} "
                                              f"({clause_ranges.TOLERANCE_MARGIN} times the solver's tolerance)")
        raise VfError(f"an angle tolerance must be below 90 deg, got {math.degrees(tolerance):g} deg", written.pos())

    def _resolution(self, given: ast.Resolution | None, shape: str, spec) -> list[int]:
        if given is None:
            return list(spec.default_resolution[shape])
        counts = given.counts
        if shape == "sphere" and len(counts) != 2:
            raise VfError(f"{spec.name} is bounded by a sphere polytope: give n x m directions", given.span.pos(),
                          hint="e.g. resolution 4x4")
        if shape == "polygon" and len(counts) != 1:
            raise VfError(f"{spec.name} is bounded by a polygon: give its number of sides", given.span.pos(),
                          hint="e.g. resolution 8")
        if min(counts) < 3:
            raise VfError("a bounded polytope needs at least 3 directions per angle", given.span.pos(),
                          hint="use 3 or more (the paper uses 4x4 for a sphere and 8 for a polygon)")
        if max(counts) > limits.RESOLUTION:
            raise limits.exceeded(f"resolution {max(counts)} is too fine", limits.RESOLUTION, given.span.pos(),
                                  hint="directions per angle of a polytope; the paper uses 4x4 and 8")
        return counts

    def _weight(self, value: ast.Value | None, scope: fx.Scope, default: float) -> float:
        if value is None:
            return default
        reader = self._scoped_reader(scope)
        weight = reader.scalar(value, u.DIMENSIONLESS, "number")
        problem = clause_ranges.WEIGHT.violation(weight)
        if problem:
            raise VfError(f"a weight {problem}, got {weight:g}", scope.source_span(value).pos(),
                          hint=f"a weight is a plain number in {clause_ranges.WEIGHT.describe()}, e.g. 10 or 1e-6")
        return weight


def _lookup_spec(name: ast.Name, table: dict, what: str, other: dict, other_hint: str):
    """The signature called ``name`` in ``table``; a helpful error when it is unknown or in ``other``."""
    if name.text in table:
        return table[name.text]
    hint = other_hint if name.text in other else suggest(name.text, table, f"{what}s")
    raise VfError(f"unknown {what} '{name.text}'", name.span.pos(), hint=hint)


def _compatible(actual: str, expected: str) -> bool:
    return actual == expected or (expected == "vector" and actual == "point")


def _named_mapping(value: ast.Value, kind: str) -> ast.Value:
    """A scene mapping reads as the composite of the param's kind: {point: .., normal: ..} -> plane(...)."""
    if isinstance(value, ast.Call) and value.name.text == "{mapping}":
        name = "bspline" if kind == "curve" else kind
        return value.model_copy(update={"name": value.name.model_copy(update={"text": name})})
    return value


def _row_estimate(c: ir.Constraint) -> int:
    """At most how many rows ``c`` adds (its polytope's directions, or 2 for a two-sided row)."""
    return math.prod(c.resolution) if c.resolution else 2


def _span(clause) -> ast.Span:
    return clause if isinstance(clause, ast.Span) else clause.span


def resolve(module: ast.Module, path: Path, libraries: list[tuple[ast.Module, u.DefaultUnits]],
            imports: list[str]) -> ir.Task:
    return Resolver(module, path, libraries).run(imports)
