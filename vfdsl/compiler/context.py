"""What a lowering sees: the symbols of one tick and the task's frames and references, in world coordinates.

Symbols: q (nq joint coordinates), u (every input, concatenated in declaration order), p (every run-time
param, flattened in declaration order; see :class:`ParamLayout`; a mesh has no run-time numbers, it moves
through its `in` pose), dt (the control period). A param declared
``in`` a pose param is transformed to the world each tick: points by R x + t, directions by R d, curves by
searching in the curve's own frame. A derived argument (``normalize(target - entry)``) is computed from its
operands' world values (:mod:`vfdsl.compiler.derived`). A ``runtime`` curve's points are run-time params
too (3 numbers a point).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import casadi as ca
import numpy as np

from vfdsl.codegen.build import CompilerUnavailable
from vfdsl.compiler import derived
from vfdsl.compiler.curve import Closest, SplineCurve
from vfdsl.compiler.geometry import homogeneous, normalize, normalize_scaled, rpy_matrix
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.kinematics.symbolic import SymbolicKinematics
from vfdsl.errors import VfError
from vfdsl.mesh.external import MeshQuery, mesh_query
from vfdsl.mesh.load import MeshFileError, read_mesh

# Run-time size of each param type (a curve's size is its points' when declared `runtime`, else 0: fixed at
# compile time, it moves through its `in` pose).
PARAM_SIZES = {"point": 3, "vector": 3, "direction": 3, "line": 6, "plane": 6, "pose": 6, "curve": 0, "mesh": 0,
               "length": 1, "angle": 1, "speed": 1, "angular_speed": 1, "number": 1, "time": 1, "force": 1}


def flatten(value: ir.Value) -> list[float]:
    """A param value as the flat numbers of its run-time slot."""
    if isinstance(value, (ir.PointValue, ir.VectorValue, ir.DirectionValue)):
        return list(value.xyz)
    if isinstance(value, ir.LineValue):
        return [*value.point, *value.direction]
    if isinstance(value, ir.PlaneValue):
        return [*value.point, *value.normal]
    if isinstance(value, ir.PoseValue):
        return [*value.translation, *value.rpy]
    if isinstance(value, ir.ScalarValue):
        return [value.value]
    if isinstance(value, ir.CurveValue) and value.runtime:
        return [x for point in value.points for x in point]
    return []


def unflatten(old, flat):
    """A param value of the same kind as ``old`` (an IR value) from the numbers of its flat run-time value."""
    v = [float(x) for x in flat]
    if isinstance(old, (ir.PointValue, ir.VectorValue, ir.DirectionValue)):
        return type(old)(xyz=v)
    if isinstance(old, ir.LineValue):
        return ir.LineValue(point=v[:3], direction=v[3:])
    if isinstance(old, ir.PlaneValue):
        return ir.PlaneValue(point=v[:3], normal=v[3:])
    if isinstance(old, ir.PoseValue):
        return ir.PoseValue(translation=v[:3], rpy=v[3:])
    if isinstance(old, ir.CurveValue):
        return ir.CurveValue(degree=old.degree, points=[v[i:i + 3] for i in range(0, len(v), 3)], runtime=True)
    if isinstance(old, ir.ScalarValue):
        return ir.ScalarValue(dimension=old.dimension, value=v[0])
    return old


@dataclass(frozen=True)
class ParamSlot:
    name: str
    type: str
    offset: int
    size: int


class ParamLayout:
    """Where each run-time param lives in the flat vector p; a procedure's captured values (``captures``: their
    slots, type and size, offsets ignored) follow the params, in :attr:`capture_slots`, each read like a param of
    its type. Their defaults are 0: the procedure writes them at its first tick (their start values)."""

    def __init__(self, params: list[ir.ParamDecl], captures: tuple[ParamSlot, ...] = ()):
        self.slots: dict[str, ParamSlot] = {}
        offset = 0
        for decl in params:
            size = PARAM_SIZES[decl.type] or len(flatten(decl.value))
            self.slots[decl.name] = ParamSlot(decl.name, decl.type, offset, size)
            offset += size
        self.capture_slots: dict[str, ParamSlot] = {}
        for c in captures:
            self.capture_slots[c.name] = ParamSlot(c.name, c.type, offset, c.size)
            offset += c.size
        self.size = offset
        self.defaults = np.concatenate([np.array(flatten(d.value), dtype=float) for d in params]
                                       + [np.zeros(offset - sum(s.size for s in self.slots.values()))])


@dataclass(frozen=True)
class FrameSymbols:
    """A task frame at the tick's q: origin p, rotation R, tool axis l = R a, Jacobian J = [Jv; Jw]."""

    p: ca.SX
    R: ca.SX
    axis: ca.SX
    J: ca.SX

    @property
    def Jv(self) -> ca.SX:
        return self.J[0:3, :]

    @property
    def Jw(self) -> ca.SX:
        return self.J[3:6, :]


@dataclass(frozen=True)
class Line:
    point: ca.SX
    direction: ca.SX


@dataclass(frozen=True)
class Plane:
    point: ca.SX
    normal: ca.SX


@dataclass(frozen=True)
class PlacedCurve:
    """A compile-time curve placed in the world by a (possibly run-time) pose: x_world = R x_local + t."""

    curve: SplineCurve
    R: ca.SX
    t: ca.SX

    def closest(self, x_world) -> tuple[ca.SX, ca.SX]:
        found = self.locate(x_world)
        return found.point, found.tangent

    def locate(self, x_world) -> Closest:
        found = self.curve.locate(self.R.T @ (x_world - self.t))
        return Closest(self.R @ found.point + self.t, self.R @ found.tangent, found.behind, found.ahead)


@dataclass(frozen=True)
class PlacedMesh:
    """A compile-time mesh placed in the world by a (possibly run-time) pose: x_world = R x_local + t; ``query``
    is its proximity query (:mod:`vfdsl.mesh.external`)."""

    query: MeshQuery
    R: ca.SX
    t: ca.SX


class ParamReader:
    """The task's argument values in world coordinates, from the flat params p (SX symbols, or DM numbers
    to evaluate them at given values). Derived arguments are evaluated by :mod:`vfdsl.compiler.derived`."""

    def __init__(self, params: list[ir.ParamDecl], p=None, captures: tuple[ParamSlot, ...] = ()):
        self.params = {decl.name: decl for decl in params}
        self.layout = ParamLayout(params, captures)
        self.p = ca.SX.sym("p", self.layout.size) if p is None else p
        self.c_sources: dict[str, Path] = {}     # C sources the tick calls into (mesh queries), by symbol

    def _raw(self, arg: ir.ParamRef | ir.Const | ir.CaptureRef) -> tuple[object, ir.Value | None]:
        """(flat symbols or numbers, IR value) of an argument, before placing it in the world (a capture: in the
        world already, no IR value)."""
        if isinstance(arg, ir.Const):
            flat = flatten(arg.value)
            return (ca.DM(flat) if flat else None), arg.value
        if isinstance(arg, ir.CaptureRef):
            slot = self.layout.capture_slots[arg.name]
            return self.p[slot.offset:slot.offset + slot.size], None
        decl = self.params[arg.name]
        slot = self.layout.slots[arg.name]
        return self.p[slot.offset:slot.offset + slot.size], decl.value

    def _pose_of(self, arg: ir.ParamRef | ir.Const) -> tuple[ca.SX, ca.SX] | None:
        if isinstance(arg, ir.ParamRef) and self.params[arg.name].frame is not None:
            flat, _ = self._raw(ir.ParamRef(name=self.params[arg.name].frame))
            return rpy_matrix(flat[3:6]), flat[0:3]
        return None

    def read(self, arg: ir.Arg):
        """A non-derived value argument, read as its own kind (lines and planes as (point, unit))."""
        kind = self.kind(arg)
        if kind in ("line", "plane"):
            line = self.line(arg)
            return line.point, line.direction
        return getattr(self, kind if kind in ("point", "vector", "direction") else "scalar")(arg)

    def kind(self, arg: ir.ParamRef | ir.Const | ir.CaptureRef | ir.Derived) -> str:
        """The kind of value an argument holds (point, direction, line, ...; a param's or a capture's type)."""
        if isinstance(arg, ir.ParamRef):
            return self.params[arg.name].type
        if isinstance(arg, ir.CaptureRef):
            return self.layout.capture_slots[arg.name].type
        return arg.kind if isinstance(arg, ir.Derived) else arg.value.kind

    def derived(self, arg: ir.Derived):
        """A derived argument's value. One that reads a capture is not checked before the tick as a param's is
        (:mod:`vfdsl.compiler.admissible`): a vector it normalizes shorter than ``derived.MIN_NORM`` (two captured
        points that coincide) gives NaN, not 0, so that its fixture's rows are undefined (the tick then holds
        still and names them, :func:`vfdsl.runtime.qp._finish`) rather than absent."""
        if derived.reads_capture(arg):
            return derived.evaluate(arg, self.read, _unit_or_nan)
        return derived.evaluate(arg, self.read)

    def point(self, arg) -> ca.SX:
        if isinstance(arg, ir.Derived):
            return self.derived(arg)
        flat, _ = self._raw(arg)
        pose = self._pose_of(arg)
        return flat if pose is None else pose[0] @ flat + pose[1]

    def vector(self, arg) -> ca.SX:
        if isinstance(arg, ir.Derived):
            return self.derived(arg)
        flat, _ = self._raw(arg)
        pose = self._pose_of(arg)
        return flat if pose is None else pose[0] @ flat

    def direction(self, arg) -> ca.SX:
        return (normalize if isinstance(arg, ir.Derived) else normalize_scaled)(self.vector(arg))

    def line(self, arg) -> Line:
        if isinstance(arg, ir.Derived):
            return Line(*self.derived(arg))
        flat, _ = self._raw(arg)
        point, direction = flat[0:3], normalize_scaled(flat[3:6])
        pose = self._pose_of(arg)
        if pose is not None:
            point, direction = pose[0] @ point + pose[1], pose[0] @ direction
        return Line(point, direction)

    def plane(self, arg) -> Plane:
        line = self.line(arg)
        return Plane(line.point, line.direction)

    def pose(self, arg) -> tuple[ca.SX, ca.SX]:
        """(R, t) of a pose argument (a pose param or a captured pose: world <- local, [t; roll, pitch, yaw])."""
        flat, _ = self._raw(arg)
        return rpy_matrix(flat[3:6]), flat[0:3]

    def scalar(self, arg) -> ca.SX:
        flat, _ = self._raw(arg)
        return flat[0]

    def mesh(self, arg, k: int) -> PlacedMesh:
        """The mesh param ``arg`` with its query of ``k`` rows (compiled once per mesh; its C source is kept in
        ``c_sources`` for the generated library). Needs a C compiler."""
        decl = self.params[arg.name]
        value = decl.value
        try:
            data = read_mesh(value.file, value.unit)
            query = mesh_query(data, k)
        except (MeshFileError, CompilerUnavailable) as exc:
            raise VfError(f"mesh '{arg.name}': {getattr(exc, 'message', exc)}", decl.span,
                          hint="a mesh fixture runs its proximity query in C, on the interpreted path too: "
                               "install gcc or clang (or set CC)") from None
        self.c_sources[query.name] = query.source
        pose = self._pose_of(arg)
        R, t = pose if pose is not None else (ca.SX.eye(3), ca.SX.zeros(3))
        return PlacedMesh(query, R, t)

    def curve(self, arg) -> PlacedCurve:
        flat, value = self._raw(arg)
        spline = SplineCurve.interpolate(np.array(value.points), value.degree)
        if value.runtime:
            spline = spline.moving(ca.reshape(flat, 3, len(value.points)).T)
        pose = self._pose_of(arg)
        R, t = pose if pose is not None else (ca.SX.eye(3), ca.SX.zeros(3))
        return PlacedCurve(spline, R, t)


class Context(ParamReader):
    """Symbols and symbolic geometry for lowering one task."""

    def __init__(self, task: ir.Task, robot: Robot):
        super().__init__(task.params, captures=capture_slots(task))
        self.task = task
        self.robot = robot
        self.nq = robot.nq
        self.q = ca.SX.sym("q", robot.nq)
        self.input_offsets: dict[str, tuple[int, int]] = {}
        offset = 0
        for decl in task.inputs:
            self.input_offsets[decl.name] = (offset, decl.size)
            offset += decl.size
        self.u = ca.SX.sym("u", offset)
        self.dt = ca.SX.sym("dt")
        self.activity = ca.SX.sym("activity", 2 * len(task.phases))   # a procedure's (tick_buffers.PHASE_ARGUMENTS)
        self._frames: dict[str, FrameSymbols] = {}
        self._closest: dict[tuple[str, str], Closest] = {}

    @cached_property
    def kinematics(self) -> SymbolicKinematics:
        return SymbolicKinematics(self.robot, self.q)

    def frame(self, name: str) -> FrameSymbols:
        if name not in self._frames:
            decl = self.task.frame(name)
            kin = self.kinematics.frame(decl.link, homogeneous(decl.offset, decl.rpy))
            self._frames[name] = FrameSymbols(kin.p, kin.R, kin.R @ ca.DM(decl.tool_axis), kin.J)
        return self._frames[name]

    def input(self, arg: ir.InputRef) -> ca.SX:
        offset, size = self.input_offsets[arg.name]
        return self.u[offset:offset + size]

    def closest_point(self, curve_arg, anchor: str, curve: PlacedCurve, x) -> Closest:
        """The curve's closest point and tangent to frame ``anchor``, built once per (curve, anchor)."""
        key = (curve_arg.model_dump_json(), anchor)
        if key not in self._closest:
            self._closest[key] = curve.locate(x)
        return self._closest[key]


def capture_slots(task: ir.Task) -> tuple[ParamSlot, ...]:
    """Every phase's captures, in phase then capture order, as slots of their type and size (offsets: 0): a
    frame's position or axis 3 numbers, its pose 6, an input its size, a param its slot's."""
    params = ParamLayout(task.params).slots
    slots = []
    for phase in task.phases:
        for c in phase.captures:
            source = c.source
            size = ((6 if source.part == "pose" else 3) if isinstance(source, ir.FrameMeasure) else
                    task.input(source.name).size if isinstance(source, ir.InputRef) else params[source.name].size)
            slots.append(ParamSlot(c.name, c.kind, 0, size))
    return tuple(slots)


def _unit_or_nan(v, node: ir.Derived):
    """v / |v|, NaN where |v| < derived.MIN_NORM (no direction). A v that reads no symbol after CasADi's folding
    (``normalize(p0 - p0)``: p0 - p0 is 0) is zero at every tick: an error here, since its constant NaN would be folded
    on (nan / nan is 1 to CasADi: a direction [1, 1, 1] the rows then held, the fixture steering at full speed)."""
    v = ca.SX(v)
    if v.is_constant() and float(ca.norm_2(ca.DM(v))) < derived.MIN_NORM:
        raise VfError("this vector is zero whatever the captures hold: it has no direction", node.span,
                      hint=derived.ZERO_HINT, code="E402")
    return ca.if_else(ca.norm_2(v) >= derived.MIN_NORM, normalize(v), ca.DM.nan(v.numel(), 1))
