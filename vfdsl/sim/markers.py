"""The fixture geometry as ROS 2 markers, for Foxglove or RViz beside the trace (``/vfdsl/fixtures``,
``visualization_msgs/msg/MarkerArray``, frame ``world``).

Each constraint's shapes (:mod:`vfdsl.sim.shapes`, what ``vfdsl view`` draws) become markers, each in a namespace
of its fixture key and shape name (``c0_stays_at_tip/polytope``, so that each can be hidden on its own): a filled mesh a ``TRIANGLE_LIST``, a wire mesh the ``LINE_LIST`` of its
edges, polyline segments a ``LINE_LIST``, points a ``SPHERE_LIST``; and a ``TEXT_VIEW_FACING`` label at its
anchor (``c0_stays_at_tip/label``) (``stays_at(tip) fixtures.vf:10 via paper_b_virtual_rcm.vf:17``). Colours are the viewer's, by role.

At MARKER_RATE, a fixture's shapes are rebuilt from the tick's joints and run-time params when a param has changed
or the frames they are drawn at (:func:`vfdsl.sim.shapes.depends_on`) have moved by more than MARKER_MOVE; a message
carries only the markers that are new or have moved by more than MARKER_MOVE since they were last written (``ADD``
replaces a marker of the same namespace and id), and ``DELETE`` for those that are gone. Markers never expire (lifetime 0),
so the latest message of each marker is the scene at any time.
"""

from __future__ import annotations

import numpy as np

from vfdsl.ir import model as ir
from vfdsl.runtime.controller import FramePose
from vfdsl.sim import shapes as sh
from vfdsl.sim.geometry import Scene

MARKER_RATE = 10.0          # Hz: the fixtures' shapes are rebuilt this often (and at the first and last tick)
MARKER_MOVE = 1e-4          # m: a marker is written again once a vertex has moved this far
LINE_WIDTH = 0.0004         # m: width of a LINE_LIST
POINT_SIZE = 0.002          # m: diameter of a SPHERE_LIST's spheres
TEXT_HEIGHT = 0.004         # m: height of a fixture's label


def shape_frames(task: ir.Task, poses: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, FramePose]:
    """The task frames as the shapes read them, from each frame's (position, rotation) in the world."""
    return {f.name: FramePose(position=np.asarray(poses[f.name][0], dtype=float).ravel(),
                              rotation=np.asarray(poses[f.name][1], dtype=float),
                              tool_axis=np.asarray(poses[f.name][1], dtype=float) @ np.asarray(f.tool_axis, dtype=float))
            for f in task.frames}


class FixtureMarkers:
    """The markers written so far, by (namespace, id), and what changed since (:meth:`update`)."""

    def __init__(self, task: ir.Task, types):
        self.task = task
        self.T = types
        self._ids: dict[tuple[str, str], int] = {}
        self._written: dict[tuple[str, str], np.ndarray] = {}
        self._built: dict[int, tuple[np.ndarray, set]] = {}     # constraint -> (drawn at, its markers' keys)

    def update(self, header, scene: Scene, frames: dict[str, FramePose], params_changed: bool) -> list:
        """The markers to write at this tick: those new or moved, and a DELETE for each one that is gone."""
        Marker = self.T["visualization_msgs/msg/Marker"]
        out, seen = [], set()
        for k, c in enumerate(self.task.constraints):
            at = sh.depends_on(c, frames)
            built = self._built.get(k)
            if built is not None and not params_changed and _close(built[0], at):
                seen |= built[1]
                continue
            fixture, keys = sh.build_one(k, self.task, scene, frames), set()
            for shape in fixture.shapes:
                keys.add((fixture.key, shape.name))
                if self._moved((fixture.key, shape.name), shape.vertices):
                    out.append(self._shape(header, fixture, shape))
            if fixture.shapes:
                keys.add((fixture.key, "label"))
                if self._moved((fixture.key, "label"), fixture.anchor):
                    out.append(self._marker(header, fixture.key, "label", Marker.TEXT_VIEW_FACING,
                                            (0.0, 0.0, TEXT_HEIGHT), (40, 40, 40), 1.0, text=fixture.label,
                                            position=fixture.anchor))
            self._built[k] = (at, keys)
            seen |= keys
        for key in [k for k in self._written if k not in seen]:
            del self._written[key]
            out.append(self._marker(header, key[0], key[1], Marker.TRIANGLE_LIST, (1.0, 1.0, 1.0), (0, 0, 0), 0.0,
                                    action=Marker.DELETE))
        return out

    def _moved(self, key: tuple[str, str], vertices: np.ndarray) -> bool:
        vertices = np.asarray(vertices, dtype=float)
        if _close(self._written.get(key), vertices):
            return False
        self._written[key] = vertices.copy()
        return True

    def _shape(self, header, fixture: sh.Fixture, shape: sh.Shape):
        Marker = self.T["visualization_msgs/msg/Marker"]
        color = sh.COLORS[fixture.soft][shape.role]
        if shape.kind == "mesh" and not shape.wireframe:
            opacity = sh.OPACITY[shape.role] or 1.0
            alpha = opacity * (0.6 if fixture.soft and sh.OPACITY[shape.role] is not None else 1.0)
            return self._marker(header, fixture.key, shape.name, Marker.TRIANGLE_LIST, (1.0, 1.0, 1.0), color, alpha,
                                points=shape.vertices[shape.faces].reshape(-1, 3))
        if shape.kind == "mesh":
            return self._marker(header, fixture.key, shape.name, Marker.LINE_LIST, (LINE_WIDTH, 0.0, 0.0), color, 1.0,
                                points=shape.vertices[_edges(shape.faces)].reshape(-1, 3))
        if shape.kind == "segments":
            return self._marker(header, fixture.key, shape.name, Marker.LINE_LIST, (LINE_WIDTH, 0.0, 0.0), color, 1.0,
                                points=np.asarray(shape.vertices).reshape(-1, 3))
        return self._marker(header, fixture.key, shape.name, Marker.SPHERE_LIST, (POINT_SIZE,) * 3, color, 1.0,
                            points=np.asarray(shape.vertices).reshape(-1, 3))

    def _marker(self, header, ns: str, name: str, kind: int, scale, rgb, alpha: float, points=(), text: str = "",
                position=(0.0, 0.0, 0.0), action: int | None = None):
        T = self.T
        Marker = T["visualization_msgs/msg/Marker"]
        ident = self._ids.setdefault((ns, name), len(self._ids))
        ns = f"{ns}/{name}"
        Point = T["geometry_msgs/msg/Point"]
        return Marker(
            header=header, ns=ns, id=ident, type=kind, action=Marker.ADD if action is None else action,
            pose=T["geometry_msgs/msg/Pose"](position=Point(x=float(position[0]), y=float(position[1]),
                                                            z=float(position[2])),
                                             orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
            scale=T["geometry_msgs/msg/Vector3"](x=float(scale[0]), y=float(scale[1]), z=float(scale[2])),
            color=T["std_msgs/msg/ColorRGBA"](r=rgb[0] / 255, g=rgb[1] / 255, b=rgb[2] / 255, a=float(alpha)),
            lifetime=T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=False,
            points=[Point(x=float(x), y=float(y), z=float(z)) for x, y, z in points], colors=[],
            texture_resource="", texture=T["sensor_msgs/msg/CompressedImage"](header=header, format="", data=np.zeros(0, np.uint8)),
            uv_coordinates=[], text=text, mesh_resource="",
            mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
            mesh_use_embedded_materials=False)


def _close(old: np.ndarray | None, new: np.ndarray) -> bool:
    """Whether points drawn at ``old`` are still where ``new`` puts them, within MARKER_MOVE."""
    return old is not None and old.shape == new.shape and np.abs(old - new).max(initial=0.0) <= MARKER_MOVE


def _edges(faces: np.ndarray) -> np.ndarray:
    """The unique edges (E x 2 vertex indices) of a triangle mesh."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(edges, axis=0)
