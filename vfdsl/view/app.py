"""The viewer: a task's robot, frames and fixtures in a viser scene, its compiled controller run live.

Scene nodes (names are stable; tests and scripts read them)::

    /robot                 the robot; /robot/link_<k> its parts, /robot/joints the joint origins
    /frames/<frame>        each task frame (axes) with /frames/<frame>/tool_axis and a label
    /fixtures/<key>        each constraint (key ``c<k>_<primitive>[_<frame>]``, k its index in the task)
                           with its shapes (/point, /polytope, /bound, /tube, /curve, /plane, ...) and /label
    /hand                  the user's hand: transform controls (live mode)
    /params/<param>        a gizmo per editable point, line, plane or pose param (live mode)
    /trace                 the tool's path, coloured by its error (replay mode)

The hand: its offset from the tool's rest pose is the task's first input. The rest pose is the tracked
frame (the frame of the first ``track`` term that reads the input): a force is ``k (p_hand - p_tool)`` with
``k = 1 / (gain T)``, so the tool reaches a still hand in about T = 0.5 s where the fixture lets it; a torque
comes from the hand's rotation and, where the input has no force part, from the hand held on the shaft
LEVER up the tool axis (the torque of the spring force about the frame); a twist is the offset over T.
"""

from __future__ import annotations

import contextlib
import io
import math
import threading
import time
from dataclasses import dataclass

import numpy as np
import viser
from pydantic import BaseModel
from scipy.spatial.transform import Rotation

from vfdsl.errors import VfError
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.primitives import CONSTRAINTS
from vfdsl.runtime.qp import StepStatus
from vfdsl.runtime.values import ASSUMED_PERIOD
from vfdsl.sim.geometry import Scene
from vfdsl.compiler.context import flatten
from vfdsl.view import replay as replay_module
from vfdsl.view import shapes as sh
from vfdsl.view.options import MAGNIFY, free_port
from vfdsl.view.robot import RobotDrawing, rotation_to_z

REACH_TIME = 0.5            # s: the hand's spring brings the tool to a still hand in about this time
LEVER = 0.05                # m: where a torque-only hand holds the tool, up its axis
DRAW_RATE = 25.0            # Hz: scene updates while running
HAND_SCALE = 0.025          # m: size of the hand's transform controls
TOOL_MOVE = 1e-4            # m: the shapes drawn at the tool are redrawn once it has moved this far

COLORS = {
    False: {"reference": (30, 100, 220), "tolerance": (70, 160, 245), "bound": (20, 50, 150),
            "forbidden": (225, 60, 45), "allowed": (60, 180, 90), "normal": (20, 150, 60)},
    True: {"reference": (235, 140, 20), "tolerance": (250, 185, 80), "bound": (190, 100, 10),
           "forbidden": (235, 110, 60), "allowed": (200, 190, 70), "normal": (200, 130, 20)},
}
OPACITY = {"tolerance": 0.45, "forbidden": 0.35, "allowed": 0.15, "reference": None, "bound": None, "normal": None}
VIOLATED = (230, 0, 40)


def wxyz(R: np.ndarray) -> np.ndarray:
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def matrix(q_wxyz) -> np.ndarray:
    w, x, y, z = q_wxyz
    return Rotation.from_quat([x, y, z, w]).as_matrix()


@dataclass
class HandModel:
    """How the hand's pose becomes the first input."""

    input: ir.InputDecl
    frame: str
    gain: float
    angular_gain: float

    @property
    def linear(self) -> bool:
        return self.input.type in ("force", "wrench", "twist")

    @property
    def angular(self) -> bool:
        return self.input.type in ("torque", "wrench", "twist")

    @property
    def lever(self) -> float:
        return LEVER if not self.linear else 0.0

    def rest(self, pose) -> tuple[np.ndarray, np.ndarray]:
        return pose.position + self.lever * pose.tool_axis, pose.rotation

    def value(self, pose, position, rotation) -> np.ndarray:
        p0, R0 = self.rest(pose)
        offset = np.asarray(position) - p0
        turn = Rotation.from_matrix(np.asarray(rotation) @ R0.T).as_rotvec()
        T = REACH_TIME
        if self.input.type == "twist":
            return np.concatenate([offset / T, turn / T])
        force = offset / (self.gain * T) if self.gain else np.zeros(3)
        torque = turn / (self.angular_gain * T) if self.angular_gain else np.zeros(3)
        if self.input.type == "force":
            return force
        if self.input.type == "wrench":
            return np.concatenate([force, torque])
        if self.angular_gain:                         # torque only: the spring on the shaft turns the tool
            torque = torque + np.cross(self.lever * pose.tool_axis, offset) / (self.angular_gain * T * self.lever ** 2)
        return torque

    def commanded(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(v, w) the track term asks for (m/s, rad/s)."""
        if self.input.type == "twist":
            return self.gain * u[:3], self.angular_gain * u[3:]
        if self.input.type == "force":
            return self.gain * u, np.zeros(3)
        if self.input.type == "torque":
            return np.zeros(3), self.angular_gain * u
        return self.gain * u[:3], self.angular_gain * u[3:]


def control_period(task: ir.Task) -> float:
    """The period the viewer runs the controller at (s): the task's, else ASSUMED_PERIOD."""
    return float(task.scene.period or ASSUMED_PERIOD)


def hand_model(task: ir.Task) -> HandModel | None:
    if not task.inputs:
        return None
    decl = task.inputs[0]
    for o in task.objectives:
        if o.term == "track" and getattr(o.args.get("input"), "name", None) == decl.name:
            gain = o.args.get("gain")
            angular = o.args.get("angular_gain")
            return HandModel(decl, o.args["frame"].name,
                             float(gain.value.value) if isinstance(gain, ir.Const) else (1.0 if decl.type == "twist" else 0.0),
                             float(angular.value.value) if isinstance(angular, ir.Const) else (1.0 if decl.type == "twist" else 0.0))
    return HandModel(decl, task.frames[0].name, 1e-3, 0.1) if task.frames else None


class Viewer:
    """One viser server showing one task. ``replay``: a :class:`vfdsl.view.replay.Trace` to play instead of
    running the controller live. The address is checked before the server starts (:func:`free_port`): a busy
    port or a wrong host is a VfError, not a server that never starts and a call that never returns."""

    def __init__(self, task: ir.Task, controller, host: str = "127.0.0.1", port: int = 8080, replay=None,
                 magnify: float = 1.0):
        self.task, self.ctrl, self.replay = task, controller, replay
        self.robot = Robot.load(task.robots[0].urdf, base_dir=None)
        self.drawing = RobotDrawing(self.robot)
        self.start = np.array(task.start if task.start is not None else np.zeros(self.robot.nq), dtype=float)
        self.period = control_period(task)
        self.magnify = magnify
        self.hand = hand_model(task) if replay is None else None
        self.lock = threading.RLock()
        self.nodes: dict[str, object] = {}
        self.scene = Scene(task)
        self.overrides: dict[str, ir.Value] = {}
        self._constraint_of = {(c.primitive, c.frame, c.span): k for k, c in enumerate(task.constraints)}
        self._violated: set[int] = set()
        self._drawn_at: dict[str, np.ndarray] = {}
        self._tool_at: dict[str, np.ndarray] = {}          # where each fixture's tool shapes were drawn
        self.message = ""
        self.ticks = 0
        self.time = 0.0
        self.status = StepStatus(0)
        self.violations: list = []
        self.readout = ""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        with contextlib.redirect_stdout(io.StringIO()):          # viser prints a banner; the command prints the URL
            self.server = viser.ViserServer(host=host, port=free_port(host, port), verbose=False)
        self.server.scene.set_up_direction("+z")
        self.q = self.start.copy()
        try:
            self.frames = controller.frames(self.q)
            self._build()
        except BaseException:
            self.close()
            raise

    # ---------------------------------------------------------------------------------------- public
    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}/"

    def start_live(self) -> None:
        """Run the controller at the task's period in a background thread (live mode)."""
        if self.replay is not None or self._thread is not None:
            return
        self._thread = threading.Thread(target=self._loop, name="vfdsl-view-loop", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()

    def push(self, offset) -> None:
        """Put the hand at the tool's rest pose plus ``offset`` (m, world), as a user dragging it would."""
        if self.hand is None:
            raise VfError(f"task '{self.task.name}' has no input: there is no hand to push")
        with self.lock:
            pose = self.frames[self.hand.frame]
            p0, R0 = self.hand.rest(pose)
            self.hand_node.position = p0 + np.asarray(offset, dtype=float)
            self.hand_node.wxyz = wxyz(R0)

    def set_param(self, name: str, value) -> bool:
        """Give a run-time param a new value (an IR value, or what ``Controller.step`` accepts); the controller
        checks it. False, and the error shown in the GUI, when it is refused."""
        with self.lock:
            candidate = dict(self.overrides)
            try:
                candidate[name] = self._as_value(name, value)
                self.ctrl.problem(self.q, self._zero_inputs(), params=candidate)
            except VfError as err:
                self._show_error(f"param '{name}' refused: {err}")
                self._place_param_gizmos()
                return False
            self.overrides = candidate
            self.scene.set_value(name, candidate[name])
            self._show_error("")
            self._draw_fixtures(force=True)
            self._place_param_gizmos()
            return True

    def reset(self) -> None:
        with self.lock:
            self.q = self.start.copy()
            self.ticks, self.time = 0, 0.0
            self.overrides = {}
            self.scene = Scene(self.task)
            self.frames = self.ctrl.frames(self.q)
            self._show_error("")
            self._static_step()
            self._draw_state()
            self._draw_fixtures(force=True)
            self._place_param_gizmos()
            for name, handle in getattr(self, "param_inputs", {}).items():
                value = self.task.param(name).value
                if isinstance(value, ir.ScalarValue):
                    handle.value = value.value / {"length": 1e-3, "angle": math.pi / 180}.get(value.dimension, 1.0)
                else:
                    handle.value = tuple(np.array(value.xyz) * (1e3 if isinstance(value, (ir.PointValue, ir.VectorValue)) else 1.0))
            if self.hand is not None:
                self.push(np.zeros(3))

    def state(self) -> dict:
        """A snapshot for scripts and tests: clients, scene node names, ticks, tool pose, status, errors."""
        with self.lock:
            names = getattr(self.server.scene, "_handle_from_node_name", None)
            frame = self.hand.frame if self.hand else (self.task.frames[0].name if self.task.frames else None)
            clients = list(self.server.get_clients().values())
            camera = None
            if clients:
                c = clients[0].camera
                camera = {"position": np.asarray(c.position).tolist(), "wxyz": np.asarray(c.wxyz).tolist(),
                          "fov": float(c.fov), "aspect": float(c.aspect)}
            return {"url": self.url, "clients": len(clients), "camera": camera,
                    "scene_nodes": sorted(names) if isinstance(names, dict) else sorted(self.nodes),
                    "ticks": self.ticks, "time": self.time, "q": self.q.tolist(),
                    "tool": None if frame is None else self.frames[frame].position.tolist(),
                    "hand": None if self.hand is None else np.asarray(self.hand_node.position).tolist(),
                    "hand_wxyz": None if self.hand is None else np.asarray(self.hand_node.wxyz).tolist(),
                    "status": int(self.status), "violations": [str(v) for v in self.violations],
                    "violated_fixtures": sorted(self._key(k) for k in self._violated),
                    "message": self.message, "readout": self.readout}

    # ------------------------------------------------------------------------------------ building
    def _build(self) -> None:
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
        self._static_step()
        self._build_gui()
        self._draw_state()
        self._draw_fixtures(force=True)
        if self.hand is not None:
            pose = self.frames[self.hand.frame]
            p0, R0 = self.hand.rest(pose)
            self.hand_node = scene.add_transform_controls(
                "/hand", scale=HAND_SCALE, position=p0, wxyz=wxyz(R0), disable_rotations=not self.hand.angular,
                depth_test=False)
            self.nodes["/hand"] = self.hand_node
            self._place_param_gizmos()
        if self.replay is not None:
            self._build_replay()
        self._camera()

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

    def _build_gui(self) -> None:
        gui = self.server.gui
        gui.configure_theme(control_width="medium")
        gui.add_markdown(f"**{self.task.name}** · `{self.task.file.rsplit('/', 1)[-1]}` · "
                         f"period {self.period * 1e3:g} ms · {self.ctrl.backend}")
        self.status_md = gui.add_markdown("")
        self.error_md = gui.add_markdown("")
        if self.replay is None and self.hand is not None:
            with gui.add_folder("Hand"):
                gui.add_markdown(f"Drag the hand: its offset from `{self.hand.frame}` is input "
                                 f"`{self.hand.input.name}` ({self.hand.input.type}).")
                self.run_box = gui.add_checkbox("Run controller", initial_value=True)
                release = gui.add_button("Release hand")
                release.on_click(lambda _: self.push(np.zeros(3)))
                reset = gui.add_button("Reset")
                reset.on_click(lambda _: self.reset())
        with gui.add_folder("Fixtures"):
            self.magnify_slider = gui.add_slider("Tolerance x", min=MAGNIFY[0], max=MAGNIFY[1], step=1,
                                                 initial_value=float(self.magnify))
            self.magnify_slider.on_update(lambda _: self._set_magnify(self.magnify_slider.value))
            self.fixture_boxes = {}
            for f in self.fixtures:
                c = self.task.constraints[f.index]
                box = gui.add_checkbox(f"{f.title} line {c.span.line}", initial_value=True,
                                       hint=f"{'soft' if f.soft else 'hard'}, {f.where}"
                                            + (f"; {f.tolerance_text}" if f.tolerance_text else ""))
                box.on_update(lambda event, key=f.key: self._show_fixture(key, event.target.value))
                self.fixture_boxes[f.key] = box
        if self.replay is None:
            self._build_param_gui()

    def _build_param_gui(self) -> None:
        gui = self.server.gui
        self.param_inputs = {}
        names = [n for n in self.ctrl.param_names]
        if not names:
            return
        with gui.add_folder("Params"):
            gui.add_markdown("Drag a param's gizmo in the scene, or type a value (mm, deg).")
            for name in names:
                decl = self.task.param(name)
                value = decl.value
                if isinstance(value, (ir.PointValue, ir.VectorValue)):
                    handle = gui.add_vector3(f"{name} (mm)", initial_value=tuple(np.array(value.xyz) * 1e3), step=0.1)
                    handle.on_update(lambda e, n=name: self.set_param(n, np.array(e.target.value) * 1e-3))
                elif isinstance(value, ir.DirectionValue):
                    handle = gui.add_vector3(name, initial_value=tuple(value.xyz), step=0.01)
                    handle.on_update(lambda e, n=name: self.set_param(n, list(e.target.value)))
                elif isinstance(value, ir.ScalarValue):
                    scale = {"length": 1e-3, "angle": math.pi / 180}.get(value.dimension, 1.0)
                    unit = {"length": " (mm)", "angle": " (deg)"}.get(value.dimension, "")
                    handle = gui.add_number(f"{name}{unit}", initial_value=value.value / scale, step=0.1 if scale != 1 else 0.01)
                    handle.on_update(lambda e, n=name, s=scale: self.set_param(n, [float(e.target.value) * s]))
                else:
                    continue
                self.param_inputs[name] = handle

    def _static_step(self) -> None:
        """One step with the hands off at the current state, not applied: which rows are violated here."""
        try:
            self.ctrl.step(self.q, self._zero_inputs(), params=self.overrides or None, dt=self.period)
        except VfError as err:
            self._show_error(str(err))
            return
        self._read_status()

    # -------------------------------------------------------------------------------- param gizmos
    def _place_param_gizmos(self) -> None:
        """A transform control per point, line, plane or pose param (and per point of a run-time curve)."""
        if self.replay is not None:
            return
        for name in self.ctrl.param_names:
            value = self.scene.values[name]
            R, t = self.scene.to_world(name)
            t = np.asarray(t).reshape(3)
            gizmos = []
            if isinstance(value, ir.PointValue):
                gizmos = [(f"/params/{name}", R @ np.array(value.xyz) + t, np.eye(3), True)]
            elif isinstance(value, (ir.LineValue, ir.PlaneValue)):
                d = value.direction if isinstance(value, ir.LineValue) else value.normal
                gizmos = [(f"/params/{name}", R @ np.array(value.point) + t, rotation_to_z(sh.unit(R @ np.array(d))), False)]
            elif isinstance(value, ir.PoseValue):
                Rp, tp = Rotation.from_euler("xyz", value.rpy).as_matrix(), np.array(value.translation)
                gizmos = [(f"/params/{name}", tp, Rp, False)]
            elif isinstance(value, ir.CurveValue) and value.runtime:
                gizmos = [(f"/params/{name}/p{i}", R @ np.array(p) + t, np.eye(3), True)
                          for i, p in enumerate(value.points)]
            for node, position, rotation, translate_only in gizmos:
                handle = self.nodes.get(node)
                if handle is None:
                    handle = self.server.scene.add_transform_controls(
                        node, scale=0.02, position=position, wxyz=wxyz(rotation), disable_rotations=translate_only,
                        line_width=1.5, opacity=0.8)
                    handle.on_update(lambda e, n=name: self._gizmo_moved(n)
                                     if getattr(e, "phase", "end") == "end" else None)
                    self.nodes[node] = handle
                else:
                    handle.position, handle.wxyz = position, wxyz(rotation)

    def _gizmo_moved(self, name: str) -> None:
        value = self.scene.values[name]
        R, t = self.scene.to_world(name)
        t = np.asarray(t).reshape(3)
        local = lambda x: R.T @ (np.asarray(x) - t)
        node = self.nodes.get(f"/params/{name}")
        if isinstance(value, ir.PointValue):
            new = ir.PointValue(xyz=list(local(node.position)))
        elif isinstance(value, ir.LineValue):
            new = ir.LineValue(point=list(local(node.position)), direction=list(R.T @ (matrix(node.wxyz) @ [0, 0, 1])))
        elif isinstance(value, ir.PlaneValue):
            new = ir.PlaneValue(point=list(local(node.position)), normal=list(R.T @ (matrix(node.wxyz) @ [0, 0, 1])))
        elif isinstance(value, ir.PoseValue):
            new = ir.PoseValue(translation=list(np.asarray(node.position, dtype=float)),
                               rpy=list(Rotation.from_matrix(matrix(node.wxyz)).as_euler("xyz")))
        elif isinstance(value, ir.CurveValue):
            points = [list(local(self.nodes[f"/params/{name}/p{i}"].position)) for i in range(len(value.points))]
            new = ir.CurveValue(degree=value.degree, points=points, runtime=True)
        else:
            return
        self.set_param(name, new)

    def _as_value(self, name: str, value) -> ir.Value:
        """An IR value of param ``name`` from what a GUI gives (lists in SI)."""
        if isinstance(value, BaseModel):                      # already an IR value
            return value
        old = self.scene.values[name]
        v = [float(x) for x in np.asarray(value, dtype=float).reshape(-1)]
        if isinstance(old, ir.PointValue):
            return ir.PointValue(xyz=v)
        if isinstance(old, ir.VectorValue):
            return ir.VectorValue(xyz=v)
        if isinstance(old, ir.DirectionValue):
            return ir.DirectionValue(xyz=v)
        if isinstance(old, ir.ScalarValue):
            return ir.ScalarValue(dimension=old.dimension, value=v[0])
        raise VfError(f"param '{name}': give {old.kind} values through its gizmo")

    # ----------------------------------------------------------------------------------- fixtures
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
        palette = COLORS[f.soft]
        for s in shapes:
            color = VIOLATED if violated and s.role != "bound" else palette[s.role]
            name = f"{base}/{s.name}"
            if s.kind == "mesh":
                opacity = OPACITY[s.role] if not s.wireframe else None
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

    # ------------------------------------------------------------------------------------- running
    def _zero_inputs(self) -> dict:
        return {d.name: np.zeros(d.size) for d in self.task.inputs}

    def _loop(self) -> None:
        next_tick = time.perf_counter()
        self._rate_mark = (time.perf_counter(), self.ticks)
        draw_every = max(1, round(1.0 / (DRAW_RATE * self.period)))
        while not self._stop.is_set():
            if getattr(self, "run_box", None) is None or self.run_box.value:
                try:
                    self.tick(draw=self.ticks % draw_every == 0)
                except Exception as err:          # shown, and the loop goes on: the viewer never dies of a tick
                    self._show_error(f"tick failed: {type(err).__name__}: {err}")
            next_tick += self.period
            delay = next_tick - time.perf_counter()
            if delay > 0:
                self._stop.wait(delay)
            else:
                next_tick = time.perf_counter()

    def tick(self, draw: bool = True) -> None:
        """One control tick: the hand's input (zero inputs for a task without one), one controller step, the
        new state."""
        with self.lock:
            inputs = self._zero_inputs()
            hand = self.hand
            if hand is not None:
                before = self.frames[hand.frame]
                u = hand.value(before, self.hand_node.position, matrix(self.hand_node.wxyz))
                inputs[hand.input.name] = u
            try:
                dq = self.ctrl.step(self.q, inputs, params=self.overrides or None, dt=self.period)
            except VfError as err:
                self._show_error(str(err))
                return
            self.q = self.q + dq
            self.ticks += 1
            self.time += self.period
            self.frames = self.ctrl.frames(self.q)
            self._read_status()
            if hand is not None:
                after = self.frames[hand.frame]
                v_cmd, w_cmd = hand.commanded(u)
                v = (after.position - before.position) / self.period
                w = Rotation.from_matrix(after.rotation @ before.rotation.T).as_rotvec() / self.period
                self.readout = _tracking(v_cmd, v, w_cmd, w, hand.linear)
            else:
                self.readout = "no input: the task runs hands off"
            if draw:
                self._draw_state()
                self._draw_fixtures()

    def _read_status(self) -> None:
        self.status = self.ctrl.status
        self.violations = self.ctrl.violations()
        violated = set()
        for v in self.violations:
            k = self._constraint_of.get((v.label.primitive, v.label.frame, v.label.span))
            if k is not None:
                violated.add(k)
        if violated != self._violated:
            changed = violated ^ self._violated
            self._violated = violated
            for f in getattr(self, "fixtures", []):
                if f.index in changed:
                    self._draw_fixture(f)

    def _draw_state(self) -> None:
        for part, (R, p, scale) in zip(self.drawing.parts, self.drawing.poses(self.q)):
            node = self.nodes[f"/robot/{part.name}"]
            node.position, node.wxyz = p, wxyz(R)
            if part.capsule:
                node.scale = tuple(scale)
        self.nodes["/robot/joints"].points = self.drawing.joints(self.q).astype(np.float32)
        for name, pose in self.frames.items():
            node = self.nodes[f"/frames/{name}"]
            node.position, node.wxyz = pose.position, wxyz(pose.rotation)
        status = "optimal" if int(self.status) == 0 else ", ".join(
            s.name.lower().replace("_", " ") for s in StepStatus if s in self.status)
        lines = [f"t = {self.time:.2f} s · tick {self.ticks} · **{status}**"]
        mark = getattr(self, "_rate_mark", None)
        if mark is not None and self.replay is None:
            now = time.perf_counter()
            if now - mark[0] > 1.0:
                self.rate = (self.ticks - mark[1]) / (now - mark[0])
                self._rate_mark = (now, self.ticks)
            if getattr(self, "rate", None):
                lines[0] += f" · {self.rate:.0f} ticks/s (period {self.period * 1e3:g} ms)"
        if self.readout:
            lines.append(self.readout)
        if self.violations:
            lines.append("violated: " + "; ".join(str(v) for v in self.violations[:4])
                         + (f" (+{len(self.violations) - 4})" if len(self.violations) > 4 else ""))
        self.status_md.content = "  \n".join(lines)

    def _show_error(self, text: str) -> None:
        self.message = text
        if hasattr(self, "error_md"):
            self.error_md.content = f"<span style='color:#c00'>{text}</span>" if text else ""

    # -------------------------------------------------------------------------------------- replay
    def _build_replay(self) -> None:
        import matplotlib
        trace = self.replay
        frame = self.task.frames[0].name
        rows = np.unique(np.linspace(0, len(trace.t) - 1, min(len(trace.t), 3000)).astype(int))
        points = np.array([self.ctrl.frames(trace.q[i])[frame].position for i in rows])
        if len(points) > 1:
            segments = np.stack([points[:-1], points[1:]], axis=1)
            if trace.error is not None and np.isfinite(trace.error[rows]).any():
                e = np.nan_to_num(trace.error[rows], nan=0.0)
                top = float(np.max(np.abs(e))) or 1.0
                rgb = matplotlib.colormaps["viridis"](np.abs(e) / top)[:, :3]
                colors = np.stack([rgb[:-1], rgb[1:]], axis=1)
                legend = f"trace of `{frame}` coloured by `{trace.error_name}`: 0 (purple) to {top * 1e3:.3g} mm (yellow)"
            else:
                colors, legend = (240, 120, 0), f"trace of `{frame}`"
            self.nodes["/trace"] = self.server.scene.add_line_segments(
                "/trace", segments.astype(np.float32), colors=colors, thickness=5.0, thickness_units="screen")
        gui = self.server.gui
        with gui.add_folder("Replay"):
            gui.add_markdown(legend if len(points) > 1 else "one row")
            self.time_slider = gui.add_slider("time (s)", min=float(trace.t[0]), max=float(max(trace.t[-1], trace.t[0] + 1e-6)),
                                              step=max(self.period, (trace.t[-1] - trace.t[0]) / 2000 or 1e-3),
                                              initial_value=float(trace.t[0]))
            self.time_slider.on_update(lambda _: self.show_time(self.time_slider.value))
            self.play_box = gui.add_checkbox("Play", initial_value=False)
        self._thread = threading.Thread(target=self._replay_loop, name="vfdsl-view-replay", daemon=True)
        self._thread.start()

    def show_time(self, t: float) -> None:
        """Show the replayed row at time t (the slider follows)."""
        with self.lock:
            if abs(self.time_slider.value - t) > 1e-9:
                self.time_slider.value = float(np.clip(t, self.time_slider.min, self.time_slider.max))
            trace = self.replay
            i = trace.index_at(t)
            self.q = trace.q[i].copy()
            self.time, self.ticks = float(trace.t[i]), i
            self.frames = self.ctrl.frames(self.q)
            moved = False
            for name, rows in trace.params.items():
                row = rows[i]
                if np.all(np.isfinite(row)) and not np.allclose(row, flatten(self.scene.values[name]), rtol=0, atol=1e-12):
                    self.scene.set_value(name, replay_module.unflatten(self.scene.values[name], row))
                    moved = True
            parts = []
            if trace.error is not None and np.isfinite(trace.error[i]):
                parts.append(f"{trace.error_name} = {trace.error[i] * 1e3:.4g} mm")
            if trace.status is not None and np.isfinite(trace.status[i]):
                parts.append(f"status {int(trace.status[i])}")
            self.readout = " · ".join(parts)
            self._draw_state()
            self._draw_fixtures(force=moved)

    def _replay_loop(self) -> None:
        while not self._stop.is_set():
            if self.play_box.value:
                t = self.time_slider.value + 1.0 / DRAW_RATE
                if t > self.replay.t[-1]:
                    t = float(self.replay.t[0])
                self.show_time(t)
            self._stop.wait(1.0 / DRAW_RATE)


def _tracking(v_cmd, v, w_cmd, w, linear: bool) -> str:
    """``asked 5.00 mm/s, moved 4.98 mm/s (100% along, 0.01 mm/s across)``, or the same in deg/s."""
    if linear:
        asked, got, unit, scale = v_cmd, v, "mm/s", 1e3
    else:
        asked, got, unit, scale = w_cmd, w, "deg/s", 180 / math.pi
    n = float(np.linalg.norm(asked))
    if n < 1e-12:
        return f"hands off · moving {np.linalg.norm(got) * scale:.3g} {unit}"
    along = float(np.dot(got, asked)) / n
    across = float(np.linalg.norm(got - along * asked / n))
    return (f"asked {n * scale:.3g} {unit}, moved {np.linalg.norm(got) * scale:.3g} {unit} "
            f"({along / n:.0%} along, {across * scale:.3g} {unit} across)")
