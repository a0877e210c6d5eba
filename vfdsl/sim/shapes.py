"""What the viewer and the MCAP trace's markers draw for each constraint, as plain meshes, polylines and points in
world coordinates (m).

Everything here is numpy and trimesh, apart from any viewer, so it is tested without a browser. The
geometry of a constraint is read from the task's params by :class:`vfdsl.sim.geometry.Scene` (params
expressed in a pose, derived arguments), the same reading the simulator scores against; the tolerance of a
polytope constraint is drawn as its real polytope (the facets of :mod:`vfdsl.compiler.geometry`, vertices
from :mod:`vfdsl.compiler.polytope`'s half-space intersection) and its guaranteed bound (the polytope's
circumradius, what ``vfdsl check`` reports) as a wire sphere or tube.

Shape roles (the viewer's colours): ``reference`` the fixture's own geometry (point, line, curve, plane,
axis; a mesh fixture's tool: the segment to its shaft and the capsule of its radius); ``tolerance`` the region
its rows allow (polytope, tube, band, cone; a mesh fixture's clearance, the capsule of radius + margin the rows
keep off the surface); ``bound`` the guaranteed bound; ``forbidden`` a region the frame must not enter;
``allowed`` a region it must stay in; ``normal`` a plane's free side. A ``moving`` shape is drawn at the tool
(:func:`tool_shapes`): the viewer redraws it as the tool moves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh
from scipy.spatial import HalfspaceIntersection

from vfdsl.compiler.geometry import polygon_angles
from vfdsl.compiler.polytope import directions
from vfdsl.ir import model as ir
from vfdsl.ir.constraints import describe, where
from vfdsl.mesh.load import read_mesh
from vfdsl.primitives import CONSTRAINTS
from vfdsl.primitives.bounds import constraint_geometry, stated_size
from vfdsl.sim.geometry import Curve, Scene, unit

PLANE_SIZE = 0.06           # m: side of the square drawn for a plane (around the frame's closest point)
LINE_LENGTH = 0.08          # m: length of a line drawn either side of the frame's closest point
AXIS_LENGTH = 0.05          # m: length of a direction's arrow and a cone's side
REFERENCE_RADIUS = 0.0006   # m: radius of the marker of a point, and of a line's or curve's polyline
SIDES = 24                  # facets of a round tube or cone that is not a polytope
COLORS = {                  # RGB of each role, for a hard (False) and a soft (True) constraint
    False: {"reference": (30, 100, 220), "tolerance": (70, 160, 245), "bound": (20, 50, 150),
            "forbidden": (225, 60, 45), "allowed": (60, 180, 90), "normal": (20, 150, 60)},
    True: {"reference": (235, 140, 20), "tolerance": (250, 185, 80), "bound": (190, 100, 10),
           "forbidden": (235, 110, 60), "allowed": (200, 190, 70), "normal": (200, 130, 20)},
}
OPACITY = {"tolerance": 0.45, "forbidden": 0.35, "allowed": 0.15, "reference": None, "bound": None, "normal": None}
"""Opacity of a filled mesh of each role (None: opaque); a soft constraint's is 0.6 times this."""
NO_GEOMETRY = {name for name, spec in CONSTRAINTS.items() if not spec.subject or spec.rate}
"""Primitives with nothing to draw: joint bounds and speed limits."""


@dataclass
class Shape:
    """One drawable: a triangle mesh (vertices, faces), polyline segments (N x 2 x 3) or points (N x 3)."""

    name: str
    kind: str                 # "mesh" | "segments" | "points"
    role: str
    vertices: np.ndarray
    faces: np.ndarray | None = None
    wireframe: bool = False
    moving: bool = False      # drawn at the tool, redrawn as it moves


@dataclass
class Fixture:
    """One ``require`` statement as the viewer shows it."""

    index: int                 # position in task.constraints
    key: str                   # scene node name under /fixtures
    title: str                 # ``stays_at(tip)``
    where: str                 # ``fixtures.vf:10 via paper_b_virtual_rcm.vf:17``
    soft: bool
    tolerance_text: str        # stated tolerance and guaranteed bound, in mm or deg
    shapes: list[Shape] = field(default_factory=list)
    anchor: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def label(self) -> str:
        return f"{self.title} {self.where}"


def fixture_key(index: int, c: ir.Constraint) -> str:
    return f"c{index}_{c.primitive}" + (f"_{c.frame}" if c.frame else "")


def build(task: ir.Task, scene: Scene, frames: dict, magnify: float = 1.0) -> list[Fixture]:
    """One :class:`Fixture` per constraint of ``task``: its shapes for the params in ``scene`` and the frame
    poses ``frames`` (name -> FramePose). ``magnify`` scales tolerances (1 = to scale)."""
    return [build_one(k, task, scene, frames, magnify) for k in range(len(task.constraints))]


def build_one(k: int, task: ir.Task, scene: Scene, frames: dict, magnify: float = 1.0) -> Fixture:
    """The :class:`Fixture` of constraint ``k`` of ``task`` (:func:`build`)."""
    c = task.constraints[k]
    fixture = Fixture(k, fixture_key(k, c), describe(c), where(c), c.soft, tolerance_text(c, task))
    frame = frames.get(c.frame) if c.frame else None
    if c.primitive not in NO_GEOMETRY and frame is not None:
        fixture.shapes = DRAWINGS[c.primitive](c, scene, frame, magnify) + tool_shapes(c, scene, frames)
        fixture.anchor = _anchor(fixture.shapes, frame.position)
    return fixture


def depends_on(c: ir.Constraint, frames: dict) -> np.ndarray:
    """The frame positions a constraint's shapes are drawn at, besides its params: its frame's when it is drawn
    around the frame (a plane's square), its frame's and shaft's when it draws the tool (a mesh fixture)."""
    spec = CONSTRAINTS[c.primitive]
    names = [c.frame] if spec.drawn_around_frame else []
    if spec.reads_mesh:
        names = [c.frame, c.args["shaft"].name]
    return np.array([frames[n].position for n in names if n in frames]).reshape(-1, 3)


def tolerance_text(c: ir.Constraint, task: ir.Task) -> str:
    """``eps 1 um, 4x4 polytope (6 facets), guaranteed 1.73 um`` (lengths in um or mm, angles in deg)."""
    stated = stated_size(c, task)
    if stated is None:
        return ""
    kind, size = stated
    g = constraint_geometry(c)
    text = f"{kind} {_quantity(size, kind)}"
    if g is not None:
        text += f", {g.label} polytope ({g.unique} facets), guaranteed {_quantity(g.circumradius * size, kind)}"
    return text


def _quantity(value: float, kind: str) -> str:
    if kind == "angle":
        return f"{math.degrees(value):.3g} deg"
    if kind == "length":
        return f"{value * 1e6:.3g} um" if abs(value) < 1e-3 else f"{value * 1e3:.3g} mm"
    return f"{value:.3g}"


def _anchor(shapes: list[Shape], fallback: np.ndarray) -> np.ndarray:
    refs = [s for s in shapes if s.role == "reference"] or shapes
    if not refs:
        return np.asarray(fallback, dtype=float)
    points = np.concatenate([s.vertices.reshape(-1, 3) for s in refs])
    return points.mean(axis=0)


# ----------------------------------------------------------------------------------------- mesh helpers
def basis(l: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """v1, v2 spanning the plane normal to the unit vector l, as the compiler builds them (paper eq. 8)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(l[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    v1 = unit(np.cross(l, helper))
    return v1, unit(np.cross(v1, l))


def sphere(center, radius: float, name: str, role: str, wireframe: bool = False, subdivisions: int = 2) -> Shape:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=max(radius, 1e-9))
    return Shape(name, "mesh", role, mesh.vertices + np.asarray(center), mesh.faces, wireframe)


def tube(points: np.ndarray, radius: float, sides: int, name: str, role: str, angles=None,
         wireframe: bool = False) -> Shape:
    """A tube of ``sides`` flat faces around a polyline; the ring's corners at ``angles`` (radians) in the
    compiler's (v1, v2) basis of each segment's direction, at distance ``radius``."""
    points = np.asarray(points, dtype=float)
    tangents = np.gradient(points, axis=0)
    angles = np.linspace(0, 2 * np.pi, sides, endpoint=False) if angles is None else np.asarray(angles)
    rings = []
    for p, t in zip(points, tangents):
        v1, v2 = basis(unit(t))
        rings.append(p + radius * (np.cos(angles)[:, None] * v1 + np.sin(angles)[:, None] * v2))
    vertices = np.concatenate(rings)
    k = len(angles)
    faces = []
    for i in range(len(points) - 1):
        for j in range(k):
            a, b = i * k + j, i * k + (j + 1) % k
            faces += [[a, b, b + k], [a, b + k, a + k]]
    return Shape(name, "mesh", role, vertices, np.array(faces, dtype=int), wireframe)


def polygon_tube(points: np.ndarray, eps: float, n: int, name: str) -> Shape:
    """The prism the n-gon rows allow around a line: faces at eps (normals u_i at a_i), corners between
    them at eps / cos(pi / n)."""
    corners = polygon_angles(n) + math.pi / n
    return tube(points, eps / math.cos(math.pi / n), n, name, "tolerance", angles=corners)


def polytope(center, eps: float, c: ir.Constraint, name: str) -> Shape | None:
    """The sphere polytope {v : u_i . v <= eps} of a constraint, at ``center``."""
    g = constraint_geometry(c)
    if g is None or not g.bounded or g.shape != "sphere":
        return None
    U = directions("sphere", g.resolution)
    vertices = HalfspaceIntersection(np.column_stack([U, -np.ones(len(U))]), np.zeros(3)).intersections
    hull = trimesh.convex.convex_hull(vertices)
    return Shape(name, "mesh", "tolerance", hull.vertices * eps + np.asarray(center), hull.faces)


def capsule(a, b, radius: float, name: str, role: str, wireframe: bool = False) -> Shape:
    """The points within ``radius`` of the segment a b (a ball when a = b)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    length = float(np.linalg.norm(b - a))
    if length == 0:
        return sphere(a, radius, name, role, wireframe)
    axis = (b - a) / length
    mesh = trimesh.creation.capsule(height=length, radius=radius, count=[SIDES, SIDES // 2])
    R = np.column_stack([*basis(axis), axis])                  # z -> the segment's direction
    return Shape(name, "mesh", role, mesh.vertices @ R.T + 0.5 * (a + b), mesh.faces, wireframe)


def segment(a, b, name: str, role: str) -> Shape:
    return Shape(name, "segments", role, np.array([[a, b]], dtype=float))


def polyline(points, name: str, role: str) -> Shape:
    points = np.asarray(points, dtype=float)
    return Shape(name, "segments", role, np.stack([points[:-1], points[1:]], axis=1))


def square(center, normal, size: float, name: str, role: str, wireframe: bool = False) -> Shape:
    v1, v2 = basis(normal)
    h = size / 2
    corners = np.array([center + h * (s1 * v1 + s2 * v2) for s1, s2 in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    return Shape(name, "mesh", role, corners, np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]]), wireframe)


def slab(center, normal, size: float, depth: float, name: str, role: str) -> Shape:
    """A box of side ``size`` on the plane's negative side (``depth`` thick)."""
    v1, v2 = basis(normal)
    box = trimesh.creation.box(extents=(size, size, depth))
    R = np.column_stack([v1, v2, normal])
    return Shape(name, "mesh", role, box.vertices @ R.T + center - normal * depth / 2, box.faces)


def cone_surface(apex, axis, half_angle: float, length: float, name: str, role: str, filled: bool = False) -> Shape:
    """The cone of unit ``axis`` and ``half_angle`` from ``apex``, its side ``length`` long."""
    v1, v2 = basis(axis)
    a = np.linspace(0, 2 * np.pi, SIDES, endpoint=False)
    ring = apex + length * (math.cos(half_angle) * axis
                            + math.sin(half_angle) * (np.cos(a)[:, None] * v1 + np.sin(a)[:, None] * v2))
    vertices = np.vstack([apex, ring, apex + length * math.cos(half_angle) * axis])
    faces = [[0, 1 + j, 1 + (j + 1) % SIDES] for j in range(SIDES)]
    if filled:
        faces += [[SIDES + 1, 1 + (j + 1) % SIDES, 1 + j] for j in range(SIDES)]
    return Shape(name, "mesh", role, vertices, np.array(faces, dtype=int))


def disk(center, normal, radius: float, name: str, role: str) -> Shape:
    v1, v2 = basis(normal)
    a = np.linspace(0, 2 * np.pi, SIDES, endpoint=False)
    ring = center + radius * (np.cos(a)[:, None] * v1 + np.sin(a)[:, None] * v2)
    vertices = np.vstack([center, ring])
    faces = [[0, 1 + j, 1 + (j + 1) % SIDES] for j in range(SIDES)]
    faces += [[0, 1 + (j + 1) % SIDES, 1 + j] for j in range(SIDES)]
    return Shape(name, "mesh", role, vertices, np.array(faces, dtype=int))


def arrow(origin, direction, length: float, name: str, role: str) -> Shape:
    """A shaft and a small cone head as segments (drawn as lines)."""
    d = unit(direction)
    tip = origin + length * d
    v1, v2 = basis(d)
    head = 0.15 * length
    segments = [[origin, tip]]
    for s in (v1, -v1, v2, -v2):
        segments.append([tip, tip - head * d + 0.4 * head * s])
    return Shape(name, "segments", role, np.array(segments, dtype=float))


# -------------------------------------------------------------------------------------- per primitive
def _eps(c: ir.Constraint, magnify: float) -> float:
    return float(c.tolerance or 0.0) * magnify


def _rho(c: ir.Constraint) -> float:
    g = constraint_geometry(c)
    return 1.0 if g is None else float(g.circumradius)


def _point_ball(c, scene, frame, magnify, point_arg, size: float):
    center = scene.point(c.args[point_arg]).reshape(3)
    shapes = [sphere(center, REFERENCE_RADIUS, "point", "reference")]
    cube = polytope(center, size, c, "polytope")
    if cube is not None:
        shapes.append(cube)
    shapes.append(sphere(center, _rho(c) * size, "bound", "bound", wireframe=True))
    return shapes


def _stays_at(c, scene, frame, magnify):
    return _point_ball(c, scene, frame, magnify, "target", _eps(c, magnify))


def _within_distance(c, scene, frame, magnify):
    return _point_ball(c, scene, frame, 1.0, "center", float(scene.scalar(c.args["distance"])))


def _line_shapes(point, direction, x, eps, c, name="line"):
    s = float(np.dot(x - point, direction))
    a, b = point + (s - LINE_LENGTH) * direction, point + (s + LINE_LENGTH) * direction
    shapes = [segment(a, b, name, "reference")]
    if eps > 0:
        n = c.resolution[0] if c.resolution else SIDES
        ends = np.array([a, b])
        shapes.append(polygon_tube(ends, eps, n, "tube"))
        shapes.append(tube(ends, eps / math.cos(math.pi / n), SIDES, "bound", "bound", wireframe=True))
    return shapes


def _along(c, scene, frame, magnify):
    point, direction = scene.line(c.args["line"])
    return _line_shapes(point.reshape(3), direction.reshape(3), frame.position, _eps(c, magnify), c)


def _follows(c, scene, frame, magnify):
    arg = c.args["curve"]
    shift = c.args.get("shift")
    value = scene.value(arg)
    offset = np.zeros(3) if shift is None else np.asarray(scene.value(shift).xyz, dtype=float)
    moved = scene.shift(arg)
    if np.ndim(moved):
        offset = offset + np.asarray(moved, dtype=float).reshape(-1)[:3]
    curve = Curve(value, shift=offset)
    R, t = scene.to_world(arg.name) if isinstance(arg, ir.ParamRef) else (np.eye(3), np.zeros(3))
    s = np.linspace(0.0, curve.length, max(60, int(curve.length / 0.001)))
    points = curve.spline(s) @ R.T + np.asarray(t).reshape(3)
    eps = _eps(c, magnify)
    shapes = [polyline(points, "curve", "reference")]
    knots = (np.asarray(value.points, dtype=float) + offset) @ R.T + np.asarray(t).reshape(3)
    shapes.append(Shape("points", "points", "reference", knots))
    if eps > 0:
        n = c.resolution[0] if c.resolution else SIDES
        shapes.append(polygon_tube(points, eps, n, "tube"))
    return shapes


def _plane_parts(c, scene, frame):
    point, normal = scene.plane(c.args["plane"])
    point, normal = point.reshape(3), normal.reshape(3)
    x = frame.position
    closest = x - np.dot(x - point, normal) * normal
    return point, normal, closest


def _above(c, scene, frame, magnify):
    _, normal, closest = _plane_parts(c, scene, frame)
    return [square(closest, normal, PLANE_SIZE, "plane", "reference"),
            slab(closest, normal, PLANE_SIZE, PLANE_SIZE / 12, "forbidden", "forbidden"),
            arrow(closest, normal, AXIS_LENGTH / 2, "free_side", "normal")]


def _on_plane(c, scene, frame, magnify):
    _, normal, closest = _plane_parts(c, scene, frame)
    eps = _eps(c, magnify)
    shapes = [square(closest, normal, PLANE_SIZE, "plane", "reference"),
              arrow(closest, normal, AXIS_LENGTH / 2, "free_side", "normal")]
    if eps > 0:
        shapes.append(square(closest + eps * normal, normal, PLANE_SIZE, "band", "tolerance", wireframe=True))
    return shapes


def _near_plane(c, scene, frame, magnify):
    _, normal, closest = _plane_parts(c, scene, frame)
    w = float(scene.scalar(c.args["half_width"]))
    return [square(closest, normal, PLANE_SIZE, "plane", "reference"),
            square(closest + w * normal, normal, PLANE_SIZE, "band_upper", "tolerance", wireframe=True),
            square(closest - w * normal, normal, PLANE_SIZE, "band_lower", "tolerance", wireframe=True)]


def _ball(c, scene, frame, role):
    center = scene.point(c.args["center"]).reshape(3)
    radius = float(scene.scalar(c.args["radius"]))
    return [sphere(center, REFERENCE_RADIUS, "center", "reference"),
            sphere(center, radius, "ball", role, subdivisions=3)]


def _within_sphere(c, scene, frame, magnify):
    return _ball(c, scene, frame, "allowed")


def _outside_sphere(c, scene, frame, magnify):
    return _ball(c, scene, frame, "forbidden")


def _keeps_direction(c, scene, frame, magnify):
    d = scene.direction(c.args["direction"]).reshape(3)
    x = frame.position
    eps = _eps(c, magnify)
    shapes = [arrow(x, d, AXIS_LENGTH, "direction", "reference")]
    if eps > 0:
        n = c.resolution[0] if c.resolution else SIDES
        shapes.append(cone_surface(x, d, eps, AXIS_LENGTH, "tolerance", "tolerance"))
        shapes.append(cone_surface(x, d, min(eps / math.cos(math.pi / n), 1.5), AXIS_LENGTH, "bound", "bound"))
        shapes[-1].wireframe = True
    return shapes


def _cone(c, scene, frame, magnify):
    axis = scene.direction(c.args["axis"]).reshape(3)
    gamma = float(scene.scalar(c.args["angle"]))
    x = frame.position
    return [arrow(x, axis, AXIS_LENGTH, "axis", "reference"),
            cone_surface(x, axis, gamma, AXIS_LENGTH, "cone", "tolerance")]


def _tilt_at_most(c, scene, frame, magnify):
    axis = scene.direction(c.args["axis"]).reshape(3)
    gamma = float(scene.scalar(c.args["angle"]))
    x = frame.position
    return [arrow(x, axis, AXIS_LENGTH, "axis", "reference"),
            cone_surface(x, axis, gamma, AXIS_LENGTH, "cone", "allowed", filled=True)]


def _rotates_around(c, scene, frame, magnify):
    axis = scene.direction(c.args["axis"]).reshape(3)
    x = frame.position
    return [arrow(x, axis, AXIS_LENGTH, "axis", "reference"),
            disk(x, axis, AXIS_LENGTH, "plane", "tolerance")]


def _passes_through(c, scene, frame, magnify):
    port = scene.point(c.args["port"]).reshape(3)
    axis, x = frame.tool_axis, frame.position
    eps = _eps(c, magnify)
    s = float(np.dot(port - x, axis))
    shapes = [sphere(port, REFERENCE_RADIUS, "port", "reference"),
              segment(x, x + (s + np.sign(s or 1) * 0.02) * axis, "shaft_line", "reference")]
    if eps > 0:
        n = c.resolution[0] if c.resolution else SIDES
        ends = np.array([port - 0.002 * axis, port + 0.002 * axis])
        shapes.append(polygon_tube(ends, eps, n, "polygon"))
        shapes.append(tube(ends, eps / math.cos(math.pi / n), SIDES, "bound", "bound", wireframe=True))
    return shapes


def _mesh(c, scene, frame, magnify):
    """The mesh in the world (placed by its pose), forbidden (outside_mesh) or allowed (inside_mesh, as a wire
    frame so the tool inside shows); the tool's shapes are :func:`tool_shapes`."""
    arg = c.args["mesh"]
    value = scene.value(arg)
    mesh = read_mesh(value.file, value.unit)
    R, t = scene.to_world(arg.name)
    inside = c.primitive == "inside_mesh"
    return [Shape("mesh", "mesh", "allowed" if inside else "forbidden", mesh.vertices @ R.T + t,
                  mesh.triangles, wireframe=inside)]


def tool_shapes(c: ir.Constraint, scene: Scene, frames: dict) -> list[Shape]:
    """What a constraint draws at the tool, redrawn as it moves (``moving``): for a mesh fixture, the capsule the
    rows keep clear, from the frame's origin a to its ``shaft`` frame's b: the segment a b (when b is not a),
    the capsule of the tool's ``radius`` around it (when not 0), and the wire capsule of radius + margin, the
    clearance the rows keep from the surface (a ball at a point tool)."""
    if not CONSTRAINTS[c.primitive].reads_mesh or c.frame not in frames or c.args["shaft"].name not in frames:
        return []
    a, b = frames[c.frame].position, frames[c.args["shaft"].name].position
    radius, margin = float(scene.scalar(c.args["radius"])), float(scene.scalar(c.args["margin"]))
    shapes = []
    if not np.array_equal(a, b):
        shapes.append(segment(a, b, "shaft", "reference"))
    if radius > 0:
        shapes.append(capsule(a, b, radius, "capsule", "reference"))
    if radius + margin > 0:
        shapes.append(capsule(a, b, radius + margin, "clearance", "tolerance", wireframe=True))
    for shape in shapes:
        shape.moving = True
    return shapes


DRAWINGS = {"stays_at": _stays_at, "within_distance": _within_distance, "along": _along, "follows": _follows,
            "above": _above, "on_plane": _on_plane, "near_plane": _near_plane, "within_sphere": _within_sphere,
            "outside_sphere": _outside_sphere, "keeps_direction": _keeps_direction, "cone": _cone,
            "tilt_at_most": _tilt_at_most, "rotates_around": _rotates_around, "passes_through": _passes_through,
            "outside_mesh": _mesh, "inside_mesh": _mesh}
"""How each primitive with geometry (all but :data:`NO_GEOMETRY`) is drawn, around its frame's pose."""
