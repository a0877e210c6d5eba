"""Declarations: the robot, task frames, inputs and params of one task file, with the values its scene sets.

One namespace for robots, frames, inputs and params (a name is declared once); exactly one robot, loaded from
its URDF; frames on robot links or on earlier frames (composed); params read as their kind (units and shapes
via :mod:`vfdsl.passes.shapes`), from the scene file where it sets them, then checked as a run-time value
would be (:mod:`vfdsl.compiler.admissible`). Each declaration is checked on its own and its mistake recorded at
its position (:mod:`vfdsl.passes.diagnostics`); a declaration that reads a failed one is not checked.
"""

from __future__ import annotations

import math
from pathlib import Path

from vfdsl import limits
from vfdsl import units as u
from vfdsl.compiler.admissible import FULL_TURN, MAX_DISTANCE, REACH_FACTOR, Admissible, plausible_distance
from vfdsl.compiler.geometry import compose, rotation
from vfdsl.errors import VfError, combined, non_finite_name, show_vector, suggest
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import ROBOTS_DIR, Robot
from vfdsl.mesh.load import MeshExtentError, MeshFileError, MeshSizeError, read_mesh
from vfdsl.passes import expressions as ex
from vfdsl.passes.diagnostics import Dependent, Errors
from vfdsl.passes.scene import SceneData, load_scene
from vfdsl.passes.shapes import LiteralReader
from vfdsl.primitives.spec import GEOMETRIC_KINDS, SCALAR_DIMENSIONS
from vfdsl.syntax import ast

PARAM_KINDS = GEOMETRIC_KINDS + tuple(SCALAR_DIMENSIONS)
_AXES = {"x": [1.0, 0.0, 0.0], "y": [0.0, 1.0, 0.0], "z": [0.0, 0.0, 1.0]}


class Declarations:
    """The declarations of one task file, read by :meth:`read`."""

    def __init__(self, module: ast.Module, path: Path, units: u.DefaultUnits):
        self.module = module
        self.path = path
        self.units = units
        self.declared: dict[str, ast.Node] = {}            # name -> its declaring statement
        self.robots: dict[str, tuple[ir.RobotDecl, Robot]] = {}
        self.frames: dict[str, ir.FrameDecl] = {}
        self.inputs: dict[str, ir.InputDecl] = {}
        self.params: dict[str, ir.ParamDecl] = {}
        self.param_values: dict[str, ast.Value] = {}        # param -> the literal its value was read from
        self.errors = Errors()
        self.failed: set[str] = set()                      # declarations whose check failed

    def read(self) -> SceneData | None:
        """Read the robot, frames, inputs and params (values from the scene where it sets them), each declaration
        checked on its own; the scene."""
        scene = self._scene(self.module.statements)
        statements = []                                     # each name's first declaration
        for stmt in self.module.statements:
            if isinstance(stmt, (ast.RobotStmt, ast.FrameStmt, ast.InputStmt, ast.ParamStmt)):
                with self.errors.each() as declared:
                    self._declare(stmt.name)
                if not declared.failed:
                    statements.append(stmt)
        for stmt in statements:
            if isinstance(stmt, ast.RobotStmt):
                self._checked(stmt, self._robot)
        if not self.robots and not self.failed:
            raise VfError("a task drives exactly one robot; none is declared", self.module.name.span,
                          hint='declare it with: robot shr = urdf "shr7"', code="E503")
        if len(self.robots) > 1:
            first, second = (decl.span for decl, _ in list(self.robots.values())[:2])
            raise VfError("a task drives exactly one robot", second,
                          hint=f"the first is declared at {first}; split the task, one per robot", code="E503")
        for stmt in statements:
            if isinstance(stmt, ast.FrameStmt):
                self._checked(stmt, self._frame)
            elif isinstance(stmt, ast.InputStmt):
                self._checked(stmt, self._input)
        self._params([s for s in statements if isinstance(s, ast.ParamStmt)], scene)
        return scene

    def _checked(self, stmt, declare) -> None:
        """``declare(stmt)``, its error recorded; a name that failed is not checked again where it is used."""
        with self.errors.each() as declaration:
            declare(stmt)
        if declaration.failed:
            self.failed.add(stmt.name.text)

    def check_param_values(self, task: ir.Task, robot: Robot) -> None:
        """The params' values (the task's defaults, or the scene's) pass the checks a run-time value gets
        (:mod:`vfdsl.compiler.admissible`); an error points at the value, in the task or the scene file."""
        admissible = Admissible(task, robot.reach)
        far = [VfError(message, span, "a point written without a unit is in the file's length unit (SI without a "
                                      "`units` statement): millimetres read as metres?", notes=notes, code="E402")
               for span, notes, message in admissible.far_constants()]
        if far:
            raise combined(far)
        p = admissible.layout.defaults
        numbers = admissible.function(p)
        i = admissible.margins.first_failure(numbers)
        if i < 0:
            return
        error = admissible.margins.error(i, numbers, p, "with the params' values, ")
        name = admissible.margins.checks[i].param
        if name is None:
            raise error.with_code("E402")
        raise VfError(error.message, self.param_values[name].span, error.hint,
                      notes=(f"param '{name}' is declared at {self.params[name].span}",), code="E402")

    def _declare(self, name: ast.Name) -> None:
        if name.text in self.declared:
            raise VfError(f"'{name.text}' is declared twice", name.span,
                          hint=f"first declared at {self.declared[name.text].span}", code="E202")
        self.declared[name.text] = name

    def _robot(self, stmt: ast.RobotStmt) -> None:
        try:
            robot = Robot.load(stmt.urdf, base_dir=self.path.parent)
        except VfError as exc:
            raise VfError(exc.message, stmt.span, exc.hint, code="E603") from None
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
            if stmt.robot.text in self.failed:
                raise Dependent
            if stmt.robot.text not in self.robots:
                hint = (f"'{stmt.robot.text}' is a frame; a frame on it is written `frame {stmt.name.text} = "
                        f"{stmt.robot.text} offset [...]`" if self._is_frame_statement(stmt.robot.text)
                        else suggest(stmt.robot.text, self.robots, "robots"))
                raise VfError(f"unknown robot '{stmt.robot.text}'", stmt.robot.span, hint=hint, code="E201")
            robot_name, link, robot = stmt.robot.text, stmt.link.text, self.robots[stmt.robot.text][1]
            if link not in robot.link_names():
                raise VfError(f"robot '{robot_name}' has no link '{link}'", stmt.link.span,
                              hint=suggest(link, robot.link_names(), "links"), code="E201")
        offset = self._literal(stmt.offset, "vector", self.units).xyz if stmt.offset else [0.0, 0.0, 0.0]
        rpy = self._literal(stmt.rotate, "rpy", self.units).xyz if stmt.rotate else [0.0, 0.0, 0.0]
        if max(map(abs, rpy)) > FULL_TURN:     # as a pose's rpy (vfdsl.compiler.admissible)
            raise VfError(f"frame '{stmt.name.text}' rotates by {show_vector(rpy)} rad: beyond a full turn",
                          stmt.rotate.span, hint="is the unit right? (bare angles take the file's `units`: radians "
                          "without one; degrees given as radians?)", code="E402")
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
                              f"'{base.name}''s overflows", stmt.span, code="E304")
        distance = math.hypot(*offset)
        if distance > limits.LENGTH:
            raise limits.exceeded(f"frame '{stmt.name.text}' is {distance:g} m from its link", limits.LENGTH,
                                  (stmt.offset.span if stmt.offset is not None else stmt.span),
                                  hint="is the unit right? (bare numbers take the file's `units`)", unit="m",
                                  code="E701")
        plausible = plausible_distance(robot.reach)    # as a point's (vfdsl.compiler.admissible)
        if distance > plausible:
            raise VfError(f"frame '{stmt.name.text}' is {distance:.3g} m from its link: beyond {plausible:.3g} m, "
                          f"{REACH_FACTOR:g} x robot '{robot_name}''s reach (at most {MAX_DISTANCE:g} m)",
                          stmt.offset.span if stmt.offset is not None else stmt.span,
                          hint="is the unit right? (bare numbers take the file's `units`: metres without one; "
                          "millimetres given as metres?)", code="E402")
        self.frames[stmt.name.text] = ir.FrameDecl(name=stmt.name.text, robot=robot_name, link=link,
                                                   offset=offset, rpy=rpy, tool_axis=axis, span=stmt.span,
                                                   base=stmt.base.text if stmt.base is not None else None)

    def _base_frame(self, stmt: ast.FrameStmt) -> ir.FrameDecl:
        name = stmt.base.text
        if name in self.frames:
            return self.frames[name]
        if name in self.failed:
            raise Dependent
        where = stmt.base.span
        if name == stmt.name.text:
            raise VfError(f"frame '{name}' is defined from itself", where,
                          hint=f"build it on a robot link: frame {name} = <robot>.link(\"...\")", code="E204")
        if self._is_frame_statement(name):
            raise VfError(f"frame '{name}' is declared later (line {self.declared[name].span.line}); a frame can "
                          f"only be built on a frame declared before it", where,
                          hint=f"move frame '{name}' above this line", code="E204")
        if name in self.robots:
            raise VfError(f"'{name}' is a robot, not a frame", where,
                          hint=f'a frame on one of its links is written: frame {stmt.name.text} = {name}.link("...")',
                          code="E203")
        if name in self.declared:
            raise VfError(f"'{name}' is not a frame", where, hint=suggest(name, self.frames, "frames"), code="E203")
        raise VfError(f"unknown frame '{name}'", where, hint=suggest(name, self.frames, "frames"), code="E201")

    def _is_frame_statement(self, name: str) -> bool:
        return any(isinstance(s, ast.FrameStmt) and s.name.text == name for s in self.module.statements)

    def _literal(self, value: ast.Value, kind: str, units: u.DefaultUnits,
                 curve_degree: int | None = None) -> ir.Value:
        """A value without names (a param's value, a frame clause): a literal, or an expression of literals."""
        if kind in ex.KINDS and ex.is_expression(value):
            return ex.Expressions(units, lambda ref: self.no_names(ref, kind), self.arg_kind, []) \
                .evaluate(value, kind).value
        return LiteralReader(units, self.no_names).read(value, kind, curve_degree=curve_degree)

    def _input(self, stmt: ast.InputStmt) -> None:
        if stmt.type.text not in INPUT_TYPES:
            raise VfError(f"unknown input type '{stmt.type.text}'", stmt.type.span,
                          hint=suggest(stmt.type.text, INPUT_TYPES, "input types"), code="E205")
        self.inputs[stmt.name.text] = ir.InputDecl(name=stmt.name.text, type=stmt.type.text, span=stmt.span)

    def _params(self, statements: list[ast.ParamStmt], scene: SceneData | None) -> None:
        by_name = {s.name.text: s for s in statements}
        for name, (_, key_span) in scene.params.items() if scene is not None else ():
            with self.errors.each():
                if name not in by_name:
                    raise VfError(f"the scene sets '{name}', which is not a param of this task", key_span,
                                  hint=suggest(name, by_name, "params"), code="E201")
        for stmt in statements:
            self._checked(stmt, lambda s: self._param(s, by_name, scene))

    def _param(self, stmt: ast.ParamStmt, by_name: dict[str, ast.ParamStmt], scene: SceneData | None) -> None:
        """One param: its type, the frame it is expressed in, its value (from the scene where it sets it)."""
        kind = stmt.type.text
        if kind not in PARAM_KINDS:
            raise VfError(f"unknown param type '{kind}'", stmt.type.span,
                          hint=suggest(kind, PARAM_KINDS, "param types"), code="E205")
        degree, runtime = self._curve_type(stmt)
        if stmt.frame is not None:
            target = by_name.get(stmt.frame.text)
            if target is None or target.type.text != "pose":
                poses = [s.name.text for s in by_name.values() if s.type.text == "pose"]
                raise VfError(f"'{stmt.frame.text}' is not a pose param", stmt.frame.span,
                              hint=suggest(stmt.frame.text, poses, "pose params"), code="E203")
            if kind == "pose":
                raise VfError("a pose cannot be expressed `in` another pose", stmt.frame.span,
                              hint="nested frames are not supported: give the pose in the robot's base frame",
                              code="E503")
            if kind not in ("point", "vector", "direction", "line", "plane", "curve", "mesh"):
                raise VfError(f"a {kind} cannot be expressed in a frame", stmt.frame.span, code="E503")
        if scene is not None and stmt.name.text in scene.params:
            source, units = scene.params[stmt.name.text][0], scene.units
        elif stmt.default is not None:
            source, units = stmt.default, self.units
        else:
            raise VfError(f"param '{stmt.name.text}' has no value", stmt.name.span,
                          hint=f"give a default (`= ...`) or set params.{stmt.name.text} in the scene file",
                          code="E504")
        source = _named_mapping(source, kind)
        self.param_values[stmt.name.text] = source
        if kind == "mesh":
            from_scene = source is not stmt.default
            self.params[stmt.name.text] = ir.ParamDecl(
                name=stmt.name.text, type=kind, value=self._mesh(stmt, source, scene if from_scene else None),
                frame=stmt.frame.text if stmt.frame else None, span=stmt.span, value_span=source.span)
            return
        value = self._literal(source, kind, units, degree)
        if runtime:
            value = value.model_copy(update={"runtime": True})
        self.params[stmt.name.text] = ir.ParamDecl(
            name=stmt.name.text, type=kind, value=value,
            frame=stmt.frame.text if stmt.frame else None, span=stmt.span, value_span=source.span)

    def _mesh(self, stmt: ast.ParamStmt, source: ast.Value, scene: SceneData | None) -> ir.MeshValue:
        """A mesh param: its file, relative to the file that names it (the task, or the scene), read with its unit
        (:mod:`vfdsl.mesh.load`): the param type's ``mesh(unit = ...)``, else the default length unit of that
        file; a scene may also write ``{file: ..., unit: ...}``."""
        units = scene.units if scene is not None else self.units
        unit = u.UNITS[units.length][1]
        for kw in stmt.type_args:
            if kw.name.text != "unit":
                raise VfError(f"mesh has no type argument '{kw.name.text}'", kw.name.span,
                              hint="state the file's unit of length: mesh(unit = 1 mm)", code="E501")
            unit = self._mesh_unit(kw.value, self.units)
        name = stmt.name.text
        example = (f'write params.{name}: "anatomy/{name}.stl", or params.{name}: {{file: anatomy/{name}.stl, unit: 1 mm}}'
                   if scene is not None else f'write param {name} : mesh(unit = 1 mm) = "anatomy/{name}.stl"')
        if scene is not None and isinstance(source, ast.Call) and source.name.text == "mesh":
            fields = {kw.name.text: kw for kw in source.kwargs}
            for name, kw in fields.items():
                if name not in ("file", "unit"):
                    raise VfError(f"a mesh in a scene has no key '{name}'", kw.name.span,
                                  hint=suggest(name, ("file", "unit"), "keys"), code="E602")
            if "file" not in fields:
                raise VfError("a mesh in a scene needs its file", source.span, hint=example, code="E602")
            if "unit" in fields:
                unit = self._mesh_unit(fields["unit"].value, units)
            source = fields["file"].value
        if not isinstance(source, ast.String):
            if scene is not None and isinstance(source, ast.Quantity):
                example = ("a file name that starts like a number (10.stl) reads as a number with a unit: write it "
                           "as ./10.stl")
            raise VfError("a mesh is given by its file name", source.span, hint=example, code="E401")
        base = scene.file.parent if scene is not None else self.path.parent
        path = (base / source.text).absolute()
        try:
            mesh = read_mesh(path, unit)
        except MeshSizeError as exc:
            raise VfError(str(exc), source.span,
                          hint=f"decimate the mesh to at most {limits.MESH_TRIANGLES:,} triangles (quadric edge "
                               "collapse): a fixture needs the anatomy's shape, not the scanner's resolution",
                          code="E604") from None
        except MeshExtentError as exc:
            raise VfError(str(exc), source.span,
                          hint="state the file's unit: {file: ..., unit: 1 mm} (without it, the param type's unit, "
                               "else the scene's length unit)" if scene is not None else
                               "state the file's unit: mesh(unit = 1 mm) (without it, the task's length unit)",
                          code="E604") from None
        except MeshFileError as exc:
            raise VfError(str(exc), source.span,
                          hint=f"the path is relative to {base.resolve()}; STL, OBJ and PLY are read",
                          code="E604") from None
        return ir.MeshValue(file=str(path), unit=unit, sha256=mesh.sha256)

    def _mesh_unit(self, value: ast.Value, units: u.DefaultUnits) -> float:
        unit = LiteralReader(units, self.no_names).scalar(value, u.LENGTH, "unit")
        if not unit > 0:
            raise VfError("a mesh's unit must be a positive length", value.span, code="E402")
        return unit

    def _curve_type(self, stmt: ast.ParamStmt) -> tuple[int | None, bool]:
        """(degree, runtime) of a curve param's type, e.g. curve(degree = 1, runtime = true)."""
        if stmt.type.text == "mesh":
            return None, False
        if stmt.type.text != "curve":
            if stmt.type_args:
                raise VfError(f"a {stmt.type.text} param takes no type arguments", stmt.type_args[0].span, code="E501")
            return None, False
        degree, runtime = None, False
        reader = LiteralReader(self.units, self.no_names)
        for kw in stmt.type_args:
            if kw.name.text == "degree":
                degree = reader.integer(kw.value, "degree")
            elif kw.name.text == "runtime":
                runtime = reader.read(kw.value, "flag").value
            else:
                raise VfError(f"curve has no type argument '{kw.name.text}'", kw.name.span,
                              hint="write curve(degree = 5), or curve(degree = 1, runtime = true)", code="E501")
        return degree, runtime

    # ---------------------------------------------------------------------------------------- scene
    def _scene(self, statements) -> SceneData | None:
        explicit = [s for s in statements if isinstance(s, ast.SceneStmt)]
        if len(explicit) > 1:
            raise VfError("only one `scene` statement per task", explicit[1].span, code="E202")
        if explicit:
            return load_scene(self.path.parent / explicit[0].path, self.units, explicit[0].span)
        default = self.path.with_suffix(".yaml")
        return load_scene(default, self.units, None) if default.is_file() else None

    def scene_ir(self, scene: SceneData | None, robot: Robot | None) -> ir.Scene | None:
        """The scene's period and start, each checked on its own (None when one failed; the start needs the
        robot)."""
        if scene is None:
            return ir.Scene()
        reader = LiteralReader(scene.units, self.no_names)
        period = start = None
        with self.errors.each() as timed:
            if scene.period is not None:
                period = self._period(scene.period, reader)
        with self.errors.each() as started:
            if scene.start is not None:
                if robot is None:
                    raise Dependent
                start = self._start(scene.start, scene.start_span, reader, robot)
        if timed.failed or started.failed:
            return None
        return ir.Scene(file=str(scene.file), start=start, period=period)

    def _period(self, value: ast.Value, reader: LiteralReader) -> float:
        period = reader.scalar(value, u.TIME, "period")
        if period <= 0:
            raise VfError("the period must be positive", value.span, code="E402")
        if period < limits.MIN_PERIOD:
            raise limits.exceeded(f"a period of {period:g} s is too short", limits.MIN_PERIOD, value.span,
                                  hint="the shortest control period is 0.01 ms (100 kHz)", unit="s", code="E701")
        if period > limits.MAX_PERIOD:
            raise limits.exceeded(f"a period of {period:g} s is too long", limits.MAX_PERIOD, value.span,
                                  hint="the longest control period is 1 s: a longer tick lets the joints' speed "
                                  "bounds allow large jumps", unit="s", code="E701")
        return period

    def _start(self, value, span: ast.Span, reader: LiteralReader, robot: Robot) -> list[float]:
        dims = [u.LENGTH if t == "prismatic" else u.ANGLE for t in robot.joint_types]
        if isinstance(value, dict):
            for name, (_, key_span) in value.items():
                if name not in robot.joint_names:
                    raise VfError(f"robot '{robot.name}' has no joint '{name}'", key_span,
                                  hint=suggest(name, robot.joint_names, "joints"), code="E201")
            missing = [n for n in robot.joint_names if n not in value]
            if missing:
                raise VfError(f"the start configuration misses joint{'s' if len(missing) > 1 else ''} "
                              f"{', '.join(missing)}", span, hint="give a value for every joint", code="E401")
            values = [value[n][0] for n in robot.joint_names]
        else:
            if not isinstance(value, ast.Vector) or len(value.items) != robot.nq:
                raise VfError(f"the start configuration needs {robot.nq} joint values "
                              f"({', '.join(robot.joint_names)})", span, code="E401")
            values = value.items
        q = [reader.scalar(v, d, "joint value") for v, d in zip(values, dims)]
        for name, x, lo, hi, v, d in zip(robot.joint_names, q, robot.lower, robot.upper, values, dims):
            if not lo - 1e-12 <= x <= hi + 1e-12:
                raise VfError(f"joint {name} starts outside its limits [{lo:g}, {hi:g}] (SI units)", v.span,
                              hint=_bare_unit_slip(v, x, lo, hi, d, reader.units), code="E402")
        return q

    def no_names(self, ref: ast.NameRef, kind: str) -> ir.Value:
        raise non_finite_name(ref.name, ref.span) or VfError(f"a name ('{ref.name}') cannot stand here; write the value "
                                                             "itself", ref.span, code="E206")


def _bare_unit_slip(value: ast.Value, x: float, lo: float, hi: float, dim: u.Dim,
                    units: u.DefaultUnits) -> str | None:
    """A hint for a start value written without a unit and read in SI (no `units` names its dimension's unit) that
    in mm (a length) or deg (an angle) would lie within the joint's limits."""
    if not isinstance(value, ast.Quantity) or value.unit is not None or units.factor(dim) != 1.0:
        return None
    unit, factor = ("mm", 1e-3) if dim == u.LENGTH else ("deg", math.pi / 180)
    if not lo - 1e-12 <= x * factor <= hi + 1e-12:
        return None
    what, si = ("length", "m") if unit == "mm" else ("angle", "rad")
    return (f"a bare {what} here is in {si} (neither the scene's nor the task's `units` names a {what} unit); "
            f"{value.number:g} {unit} is within the limits: write `{value.number:g} {unit}`, or give the scene "
            "`units: mm, deg`")


def _named_mapping(value: ast.Value, kind: str) -> ast.Value:
    """A scene mapping reads as the composite of the param's kind: {point: .., normal: ..} -> plane(...)."""
    if isinstance(value, ast.Call) and value.name.text == "{mapping}":
        name = "bspline" if kind == "curve" else kind
        return value.model_copy(update={"name": value.name.model_copy(update={"text": name})})
    return value
