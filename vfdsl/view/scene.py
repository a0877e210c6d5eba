"""The scene: the robot, the task's frames and the fixtures drawn in viser, redrawn as the tool moves.

A part of :class:`vfdsl.view.app.Viewer`: it draws into ``self.server.scene`` and keeps the nodes it makes in
``self.nodes`` (name -> handle), from the viewer's task, scene, frames, magnification and violated fixtures.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS
from vfdsl.sim import shapes as sh

DRAW_RATE = 25.0            # Hz: scene updates while running or playing
TOOL_MOVE = 1e-4            # m: the shapes drawn at the tool are redrawn once it has moved this far

VIOLATED = (230, 0, 40)


def wxyz(R: np.ndarray) -> np.ndarray:
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def matrix(q_wxyz) -> np.ndarray:
    w, x, y, z = q_wxyz
    return Rotation.from_quat([x, y, z, w]).as_matrix()


class SceneDrawing:
    """The viewer's scene: the robot and frames (:meth:`_build_scene`, :meth:`_draw_robot`) and the fixtures
    (:meth:`_draw_fixtures`)."""

    def _build_scene(self) -> None:
        """The robot's parts and joints, and each frame with its tool axis and label."""
        scene = self.server.scene
        self.nodes["/robot"] = scene.add_frame("/robot", show_axes=False)
        for part in self.drawing.parts:
            self.nodes[f"/robot/{part.name}"] = scene.add_mesh_simple(
                f"/robot/{part.name}", part.vertices, part.faces, color=(150, 150, 160), flat_shading=False)
        joints = self.drawing.joints(self.q)
        self.nodes["/robot/joints"] = scene.add_point_cloud("/robot/joints", joints, colors=(90, 90, 100),
                                                            point_size=0.004, point_shape="circle")
        for f in self.task.frames:
            name = f"/frames/{f.name}"
            self.nodes[name] = scene.add_frame(name, axes_length=0.015, axes_radius=0.0006, origin_radius=0.0015)
            axis = np.array([[[0, 0, 0], np.asarray(f.tool_axis) * 0.04]])
            self.nodes[f"{name}/tool_axis"] = scene.add_line_segments(
                f"{name}/tool_axis", axis, colors=(200, 0, 200), thickness=3.0, thickness_units="screen")
            self.nodes[f"{name}/label"] = scene.add_label(f"{name}/label", f.name, position=(0, 0, 0.004))
        self.fixtures = sh.build(self.task, self.scene, self.frames, self.magnify)

    def _camera(self, direction=(0.7, -1.0, 1.1), distance: float = 2.2) -> None:
        """Point the initial camera at the frames and fixtures, from ``direction`` (world), ``distance`` times
        their extent away."""
        points = [p.position for p in self.frames.values()]
        points += [f.anchor for f in self.fixtures if f.shapes]
        points = np.array(points) if points else np.zeros((1, 3))
        center = points.mean(axis=0)
        extent = max(0.06, 1.6 * float(np.max(np.linalg.norm(points - center, axis=1))))
        direction = np.asarray(direction, dtype=float)
        self.server.initial_camera.look_at = center
        self.server.initial_camera.position = center + extent * distance * direction / np.linalg.norm(direction)
        self.server.initial_camera.up = (0.0, 0.0, 1.0)
        self.server.initial_camera.near = 0.001

    def _draw_robot(self) -> None:
        """The robot's parts and joints and the frames at the current q."""
        for part, (R, p, scale) in zip(self.drawing.parts, self.drawing.poses(self.q)):
            node = self.nodes[f"/robot/{part.name}"]
            node.position, node.wxyz = p, wxyz(R)
            if part.capsule:
                node.scale = tuple(scale)
        self.nodes["/robot/joints"].points = self.drawing.joints(self.q).astype(np.float32)
        for name, pose in self.frames.items():
            node = self.nodes[f"/frames/{name}"]
            node.position, node.wxyz = pose.position, wxyz(pose.rotation)

    def _set_magnify(self, value: float) -> None:
        with self.lock:
            self.magnify = float(value)
            self._draw_fixtures(force=True)

    def _show_fixture(self, key: str, visible: bool) -> None:
        node = self.nodes.get(f"/fixtures/{key}")
        if node is not None:
            node.visible = bool(visible)

    def _key(self, index: int) -> str:
        return sh.fixture_key(index, self.task.constraints[index])

    def _draw_fixtures(self, force: bool = False) -> None:
        """Rebuild the fixtures' shapes: all of them (``force``), or those drawn around a frame that has moved
        more than 2 mm since (a plane's square, a line's stretch, a cone's apex); and the shapes drawn at the tool
        (a mesh fixture's capsule) whenever it has moved more than TOOL_MOVE."""
        stale, moved = set(), set()
        for k, c in enumerate(self.task.constraints):
            key = sh.fixture_key(k, c)
            if c.frame in self.frames and (key not in self._drawn_at or (
                    CONSTRAINTS[c.primitive].drawn_around_frame
                    and np.linalg.norm(self.frames[c.frame].position - self._drawn_at[key]) > 0.002)):
                stale.add(k)
            elif key in self._tool_at and np.abs(self._tool(c) - self._tool_at[key]).max() > TOOL_MOVE:
                moved.add(k)
        if force or stale:
            self.fixtures = sh.build(self.task, self.scene, self.frames, self.magnify)
        for f in getattr(self, "fixtures", []):
            c = self.task.constraints[f.index]
            if force or f.index in stale:
                self._draw_fixture(f)
                if c.frame in self.frames:
                    self._drawn_at[f.key] = self.frames[c.frame].position.copy()
            elif f.index in moved:
                for s in f.shapes:
                    node = self.nodes.pop(f"/fixtures/{f.key}/{s.name}", None) if s.moving else None
                    if node is not None:
                        node.remove()
                tool = sh.tool_shapes(c, self.scene, self.frames)
                f.shapes = [s for s in f.shapes if not s.moving] + tool
                self._draw_shapes(f, tool)
            if any(s.moving for s in f.shapes):
                self._tool_at[f.key] = self._tool(c)

    def _tool(self, c: ir.Constraint) -> np.ndarray:
        """Where the shapes drawn at the tool of ``c`` are: its frame's origin and its shaft frame's."""
        shaft = c.args["shaft"].name if "shaft" in c.args else c.frame
        return np.array([self.frames[c.frame].position, self.frames[shaft].position])

    def _draw_fixture(self, f: sh.Fixture) -> None:
        scene = self.server.scene
        base = f"/fixtures/{f.key}"
        for name in [n for n in self.nodes if n.startswith(base + "/")]:
            self.nodes.pop(name).remove()
        box = getattr(self, "fixture_boxes", {}).get(f.key)
        if base not in self.nodes:
            self.nodes[base] = scene.add_frame(base, show_axes=False)
        self.nodes[base].visible = True if box is None else bool(box.value)
        self._draw_shapes(f, f.shapes)
        violated = f.index in self._violated
        text = ("VIOLATED " if violated else "") + ("soft " if f.soft and not f.title.startswith("soft") else "") \
            + f.label
        if f.shapes:
            self.nodes[f"{base}/label"] = scene.add_label(f"{base}/label", text, position=f.anchor,
                                                          font_screen_scale=0.8)

    def _draw_shapes(self, f: sh.Fixture, shapes: list[sh.Shape]) -> None:
        scene = self.server.scene
        base = f"/fixtures/{f.key}"
        violated = f.index in self._violated
        palette = sh.COLORS[f.soft]
        for s in shapes:
            color = VIOLATED if violated and s.role != "bound" else palette[s.role]
            name = f"{base}/{s.name}"
            if s.kind == "mesh":
                opacity = sh.OPACITY[s.role] if not s.wireframe else None
                if f.soft and opacity is not None:
                    opacity *= 0.6
                node = scene.add_mesh_simple(name, s.vertices.astype(np.float32), s.faces.astype(np.uint32),
                                             color=color, wireframe=s.wireframe or (f.soft and s.role == "tolerance"),
                                             opacity=opacity, side="double", cast_shadow=False,
                                             receive_shadow=False)
            elif s.kind == "segments":
                node = scene.add_line_segments(name, s.vertices.astype(np.float32), colors=color,
                                               thickness=2.0 if f.soft else 3.0, thickness_units="screen")
            else:
                node = scene.add_point_cloud(name, s.vertices.astype(np.float32), colors=color, point_size=0.002,
                                             point_shape="circle")
            self.nodes[name] = node
