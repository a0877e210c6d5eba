"""Scoring a run: each constraint's error in its own units, measured on the simulator's exact kinematics
(the encoders) and, for frame poses, by the simulated tracker.

The error of a constraint is how far the frame is from the set the constraint describes (0 inside it), one
function per primitive in :data:`ERRORS`, in the dimension its spec states (``ConstraintSpec.metric``):

    stays_at          |p - target|                         mm
    along             distance from p to the line          mm
    follows           distance from p to the (shifted) curve, in the curve's frame, ends included
                      (past an end: the distance to the end point, as the paper scores)   mm
    on_plane          |n . (p - p0)|                       mm
    above             max(0, -n . (p - p0))                mm
    within_distance   max(0, |p - c| - distance)           mm
    within_sphere     max(0, |p - c| - radius)             mm
    outside_sphere    max(0, radius - |p - c|)             mm
    near_plane        max(0, |n . (p - p0)| - half_width)  mm
    passes_through    distance from the port to the tool axis line   mm
    cone              | angle(l, axis) - angle |           deg
    tilt_at_most      max(0, angle(l, axis) - angle)       deg
    outside_mesh,     max(0, margin - clearance), the clearance of the capsule from the frame to its shaft frame
    inside_mesh       (less its radius), by coal's BVH distance and pseudo-normals (vfdsl.mesh.clearance)   mm
                      and, as a second metric <...>_contact_pct, the share of ticks the tool is on its margin
                      (clearance <= margin + CONTACT_BAND): the time in contact   %
                      and, as a third, <...>_clearance_mm: the clearance itself (negative through the surface),
                      whose min is the run's minimum clearance   mm
    keeps_direction   angle(l, direction)                  deg
    rotates_around    | 90 deg - angle(l, axis) |          deg
    speed             max(0, |p_k - p_k-1| / dt - max)     mm/s
    angular_speed     max(0, |rotation angle of R_k-1^T R_k| / dt - max)   deg/s
    joint_limits      max over joints of the distance outside [lower, upper]    mm (prismatic), deg (revolute)
    joint_speed       max over joints of max(0, |q_k - q_k-1| / dt - fraction * velocity limit)   mm/s, deg/s

with p the frame's origin, l its tool axis, and the geometry the one in force at each sample: where a scene's
motions move a param, every sample is scored against its moved value (:class:`~vfdsl.sim.geometry.Scene`).
Every metric has one sample per tick, on the ticks' time base t_k = k dt: a speed at tick k is that of the step
that ended there (backward differences), and the first tick of a segment (the run's start, or a disturbance)
has no step before it in the segment and scores 0. A scene may name an error (``pivot_error: {error_of: tip
stays_at}``) or add the tilt of a frame's tool axis from a pose param's z axis (the plate normal).
Statistics pool every tick of every trial: mean, std, min, max.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from vfdsl.ir import captures
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh.clearance import mesh_clearance
from vfdsl.mesh.load import read_mesh
from vfdsl.primitives import CONSTRAINTS
from vfdsl.sim.geometry import Curve, Scene, pose_matrix
from vfdsl.sim.robot import LinkPose, frame_offset
from vfdsl.sim.settings import MetricSpec, constraint_of

# dimension -> (display unit, factor from SI)
DISPLAY = {"length": ("mm", 1e3), "angle": ("deg", 180 / math.pi), "speed": ("mm/s", 1e3),
           "angular_speed": ("deg/s", 180 / math.pi), "contact": ("%", 100.0), "clearance": ("mm", 1e3)}
_SUFFIX = {"mm": "mm", "deg": "deg", "mm/s": "mm_s", "deg/s": "deg_s", "%": "pct"}
_REVOLUTE = {"length": "angle", "speed": "angular_speed"}     # a joint metric's dimension on revolute joints
CONTACT_BAND = 0.05e-3
"""m: a tool within this of its margin is in contact with the fixture's surface."""


@dataclass
class Poses:
    """Frame poses over a run: origin p (N x 3) and rotation R (N x 3 x 3) of each task frame; ``clearances``
    keeps each mesh fixture's clearance at these poses, which three metrics read; ``progress(n)``, when given, is
    called as the clearances of n more samples are measured (the slow part of scoring a run)."""

    p: dict[str, np.ndarray]
    R: dict[str, np.ndarray]
    clearances: dict = field(default_factory=dict, repr=False)
    progress: Callable[[int], None] | None = field(default=None, repr=False)

    def axis(self, frame: ir.FrameDecl) -> np.ndarray:
        return self.R[frame.name] @ np.asarray(frame.tool_axis)


def frame_poses(robot: Robot, task: ir.Task, qs: np.ndarray) -> Poses:
    """Every task frame's pose at every row of ``qs``: Pinocchio's forward kinematics of each link once
    per sample, then the frames' offsets (T_world_frame = T_world_link @ offset) for all samples at once."""
    links = {}
    for link in dict.fromkeys(f.link for f in task.frames):
        pose = LinkPose(robot, link)
        p_link, R_link = np.empty((len(qs), 3)), np.empty((len(qs), 3, 3))
        for i, q in enumerate(qs):
            p_link[i], R_link[i] = pose(q)
        links[link] = (p_link, R_link)
    p, R = {}, {}
    for frame in task.frames:
        offset = frame_offset(frame)
        p_link, R_link = links[frame.link]
        p[frame.name] = p_link + R_link @ offset[:3, 3]
        R[frame.name] = R_link @ offset[:3, :3]
    return Poses(p, R)


@dataclass(frozen=True)
class MetricDef:
    """One metric: its name, unit, the constraint or spec it scores, and the paper's figures beside it."""

    name: str
    unit: str
    dimension: str
    constraint: ir.Constraint | None = None
    spec: MetricSpec | None = None
    joint_kind: str | None = None            # joint metrics: "prismatic" or "revolute"
    tolerance: float | None = None           # display units
    pose_based: bool = True                  # measurable by the tracker
    phase: str | None = None                 # a procedure's phase whose fixture it measures (only in that phase)


def metric_defs(task: ir.Task, robot: Robot, specs: tuple[MetricSpec, ...]) -> list[MetricDef]:
    """The metrics of a task: every constraint's error (named by the scene where it says so), a procedure's
    phases' too (named after their phase: ``insert_needle_along_error_mm``; of the task of
    :func:`vfdsl.ir.captures.as_params`, a fixture reading a capture it leaves one has none), then the scene's
    tilt metrics."""
    named = {id(constraint_of(task, s.error_of)): s for s in specs if s.error_of}
    defs: list[MetricDef] = []
    stated = [(None, c) for c in task.constraints]
    stated += [(p.name, c) for p in task.phases for c in p.constraints if captures.readable(c)]
    for phase, c in stated:
        spec = named.get(id(c))
        primitive = CONSTRAINTS[c.primitive]
        prefix = f"{phase}_" if phase else ""
        if not primitive.subject:            # a joint primitive: one metric per joint kind
            dims = (primitive.metric, _REVOLUTE[primitive.metric])
            for kind, dim in zip(("prismatic", "revolute"), dims):
                if any(_joint_kind(t) == kind for t in robot.joint_types):
                    unit, _ = DISPLAY[dim]
                    defs.append(MetricDef(f"{prefix}{c.primitive}_{_SUFFIX[unit]}", unit, dim, c, joint_kind=kind,
                                          pose_based=False, phase=phase))
            continue
        dim = primitive.metric
        unit, factor = DISPLAY[dim]
        base = spec.name if spec else f"{prefix}{c.frame}_{c.primitive}_error"
        tolerance = c.tolerance * factor if c.tolerance is not None else None
        defs.append(MetricDef(f"{base}_{_SUFFIX[unit]}", unit, dim, c, spec, tolerance=tolerance, phase=phase))
        if primitive.reads_mesh:
            base = spec.name if spec else f"{prefix}{c.frame}_{c.primitive}"
            defs.append(MetricDef(f"{base}_contact_pct", "%", "contact", c, spec, phase=phase))
            defs.append(MetricDef(f"{base}_clearance_mm", "mm", "clearance", c, spec, phase=phase))
    for s in specs:
        if s.tilt_of:
            defs.append(MetricDef(f"{s.name}_deg", "deg", "angle", spec=s))
    seen: dict[str, int] = {}
    unique = []
    for d in defs:
        seen[d.name] = seen.get(d.name, 0) + 1
        if seen[d.name] > 1 and d.constraint is not None:
            d = MetricDef(**{**d.__dict__, "name": f"{d.name}_line{d.constraint.span.line}"})
        unique.append(d)
    return unique


def _joint_kind(joint_type: str) -> str:
    return "prismatic" if joint_type == "prismatic" else "revolute"


def errors(d: MetricDef, task: ir.Task, robot: Robot, scene: Scene, poses: Poses, qs: np.ndarray,
           period: float) -> np.ndarray:
    """The metric at every sample of one segment (constant scene), in display units."""
    _, factor = DISPLAY[d.dimension]
    if d.spec is not None and d.spec.tilt_of:
        frame = task.frame(d.spec.tilt_of)
        normal = pose_matrix(scene.values[d.spec.normal_of])[0][:, 2]
        return np.degrees(np.arccos(np.clip(np.abs(poses.axis(frame) @ normal), -1, 1)))
    return factor * ERRORS[d.constraint.primitive](d, Measured(task, robot, scene, poses, qs, period))


@dataclass(frozen=True)
class Measured:
    """What a metric is measured on: one segment of a run (a constant scene) and its samples."""

    task: ir.Task
    robot: Robot
    scene: Scene
    poses: Poses
    qs: np.ndarray
    period: float

    def origin(self, c: ir.Constraint) -> np.ndarray:
        return self.poses.p[c.frame]

    def axis(self, c: ir.Constraint) -> np.ndarray:
        return self.poses.axis(self.task.frame(c.frame))


def _mesh_clearance(c: ir.Constraint, scene: Scene, poses: Poses) -> np.ndarray:
    """The clearance of the constraint's capsule from its mesh at every sample, in the mesh's frame (computed once
    per constraint and scene for these poses)."""
    key = (id(c), id(scene))
    if key not in poses.clearances:
        poses.clearances[key] = (scene, _clearance(c, scene, poses))     # the scene held: its id stays its own
    return poses.clearances[key][1]


def _clearance(c: ir.Constraint, scene: Scene, poses: Poses) -> np.ndarray:
    value = scene.value(c.args["mesh"])
    mesh = read_mesh(value.file, value.unit)
    a = np.atleast_2d(scene.local(c.args["mesh"], poses.p[c.frame]))
    b = np.atleast_2d(scene.local(c.args["mesh"], poses.p[c.args["shaft"].name]))
    return mesh_clearance(mesh)(a, b, scene.scalar(c.args["radius"]), c.primitive == "inside_mesh", poses.progress)


def prepare_meshes(task: ir.Task) -> None:
    """Build the clearance query (BVH and pseudo-normals) of every mesh a metric of ``task`` reads, once per process
    and before the trials (like the controller), so that a run's wall time is its trials'."""
    scene = Scene(task)
    for c in task.constraints:
        if CONSTRAINTS[c.primitive].reads_mesh:
            value = scene.value(c.args["mesh"])
            mesh_clearance(read_mesh(value.file, value.unit))


def _stays_at(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.linalg.norm(m.origin(c) - m.scene.point(c.args["target"]), axis=1)


def _distance_to_center(c: ir.Constraint, m: Measured) -> np.ndarray:
    return np.linalg.norm(m.origin(c) - m.scene.point(c.args["center"]), axis=1)


def _within_distance(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.maximum(0.0, _distance_to_center(c, m) - m.scene.scalar(c.args["distance"]))


def _within_sphere(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.maximum(0.0, _distance_to_center(c, m) - m.scene.scalar(c.args["radius"]))


def _outside_sphere(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.maximum(0.0, m.scene.scalar(c.args["radius"]) - _distance_to_center(c, m))


def _along(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    point, direction = m.scene.line(c.args["line"])
    return np.linalg.norm(np.cross(m.origin(c) - point, direction), axis=-1)


def _height(c: ir.Constraint, m: Measured) -> np.ndarray:
    """n . (p - p0): the frame origin's signed height over the constraint's plane."""
    point, normal = m.scene.plane(c.args["plane"])
    return np.sum((m.origin(c) - point) * normal, axis=-1)


def _on_plane(d: MetricDef, m: Measured) -> np.ndarray:
    return np.abs(_height(d.constraint, m))


def _above(d: MetricDef, m: Measured) -> np.ndarray:
    return np.maximum(0.0, -_height(d.constraint, m))


def _near_plane(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.maximum(0.0, np.abs(_height(c, m)) - m.scene.scalar(c.args["half_width"]))


def _passes_through(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.linalg.norm(np.cross(m.scene.point(c.args["port"]) - m.origin(c), m.axis(c)), axis=1)


def _follows(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    scene, curve_arg, shift = m.scene, c.args["curve"], c.args.get("shift")
    curve = _curve(scene.value(curve_arg), tuple(scene.value(shift).xyz) if shift is not None else (0, 0, 0))
    return curve.closest(np.atleast_2d(scene.local(curve_arg, m.origin(c)) - scene.shift(shift)))[1]


def _angle_to(c: ir.Constraint, m: Measured, name: str) -> np.ndarray:
    """angle(l, a): the tool axis' angle from the direction argument ``name``."""
    return np.arccos(np.clip(np.sum(m.axis(c) * m.scene.direction(c.args[name]), axis=-1), -1.0, 1.0))


def _keeps_direction(d: MetricDef, m: Measured) -> np.ndarray:
    return _angle_to(d.constraint, m, "direction")


def _rotates_around(d: MetricDef, m: Measured) -> np.ndarray:
    return np.abs(np.pi / 2 - _angle_to(d.constraint, m, "axis"))


def _cone(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.abs(_angle_to(c, m, "axis") - m.scene.scalar(c.args["angle"]))


def _tilt_at_most(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    return np.maximum(0.0, _angle_to(c, m, "axis") - m.scene.scalar(c.args["angle"]))


def _speed(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    speed = np.linalg.norm(_steps(m.origin(c)), axis=1) / m.period
    return np.maximum(0.0, speed - m.scene.scalar(c.args["max"]))


def _angular_speed(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    R = m.poses.R[c.frame]
    relative = np.einsum("nji,njk->nik", np.concatenate([R[:1], R[:-1]]), R)
    cos = np.clip((np.trace(relative, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)
    return np.maximum(0.0, np.arccos(cos) / m.period - m.scene.scalar(c.args["max"]))


def _mesh(d: MetricDef, m: Measured) -> np.ndarray:
    """The metric's dimension says which: the error max(0, margin - clearance), the contact (1 on the margin)
    or the clearance itself."""
    c = d.constraint
    margin = m.scene.scalar(c.args["margin"])
    clearance = _mesh_clearance(c, m.scene, m.poses)
    if d.dimension == "contact":
        return clearance <= margin + CONTACT_BAND
    if d.dimension == "clearance":
        return clearance
    return np.maximum(0.0, margin - clearance)


def _steps(x: np.ndarray) -> np.ndarray:
    """The step that ended at each sample, x_k - x_k-1 (zero at the first): one per tick, like the others."""
    return np.diff(x, axis=0, prepend=x[:1])


_CURVES: dict = {}


def _curve(value: ir.CurveValue, shift: tuple) -> Curve:
    key = (value.model_dump_json(), shift)
    if key not in _CURVES:
        _CURVES[key] = Curve(value, shift)
    return _CURVES[key]


def _joint_mask(d: MetricDef, m: Measured) -> np.ndarray:
    return np.array([_joint_kind(t) == d.joint_kind for t in m.robot.joint_types])


def _joint_limits(d: MetricDef, m: Measured) -> np.ndarray:
    outside = np.maximum(m.robot.lower - m.qs, m.qs - m.robot.upper)
    return np.maximum(0.0, outside[:, _joint_mask(d, m)]).max(axis=1)


def _joint_speed(d: MetricDef, m: Measured) -> np.ndarray:
    c = d.constraint
    speed = np.abs(_steps(m.qs)) / m.period
    # a param's value, one a sample where a scene's motion moves it
    fraction = np.reshape(m.scene.scalar(c.args["fraction"]), (-1, 1)) if "fraction" in c.args else 1.0
    return np.maximum(0.0, speed - fraction * m.robot.velocity_limit)[:, _joint_mask(d, m)].max(axis=1)


ERRORS: dict[str, Callable[[MetricDef, Measured], np.ndarray]] = {
    "stays_at": _stays_at, "within_distance": _within_distance, "within_sphere": _within_sphere,
    "outside_sphere": _outside_sphere, "along": _along, "on_plane": _on_plane, "above": _above,
    "near_plane": _near_plane, "passes_through": _passes_through, "follows": _follows,
    "keeps_direction": _keeps_direction, "rotates_around": _rotates_around, "cone": _cone,
    "tilt_at_most": _tilt_at_most, "speed": _speed, "angular_speed": _angular_speed,
    "outside_mesh": _mesh, "inside_mesh": _mesh, "joint_limits": _joint_limits, "joint_speed": _joint_speed,
}
"""Each primitive's true error in SI units, simulate's own numpy geometry (an oracle independent of the
compiled rows), as the table at the top of this module states it."""


@dataclass
class Stats:
    """One metric pooled over samples (and trials, merged in trial order): count, mean, sum of squared
    deviations (merged by Chan et al.'s pairwise formula, exact for a near-constant metric), max and min."""

    count: int = 0
    mean: float = 0.0
    squares: float = 0.0                     # sum of (x - mean)^2
    worst: float = 0.0                       # max
    least: float = 0.0                       # min

    def add(self, values: np.ndarray) -> "Stats":
        if values.size:
            mean = float(values.mean())
            part = Stats(int(values.size), mean, float(((values - mean) ** 2).sum()), float(values.max()),
                         float(values.min()))
            merged = self.merge(part)
            self.count, self.mean, self.squares = merged.count, merged.mean, merged.squares
            self.worst, self.least = merged.worst, merged.least
        return self

    def merge(self, other: "Stats") -> "Stats":
        if not other.count:
            return Stats(self.count, self.mean, self.squares, self.worst, self.least)
        if not self.count:
            return Stats(other.count, other.mean, other.squares, other.worst, other.least)
        count = self.count + other.count
        delta = other.mean - self.mean
        return Stats(count, self.mean + delta * other.count / count,
                     self.squares + other.squares + delta * delta * self.count * other.count / count,
                     max(self.worst, other.worst), min(self.least, other.least))

    @property
    def std(self) -> float:
        return math.sqrt(self.squares / self.count) if self.count else 0.0

    def summary(self) -> dict:
        return {"mean": self.mean, "std": self.std, "min": self.least, "max": self.worst, "samples": self.count}
