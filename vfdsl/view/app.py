"""The viewer: a task's robot, frames and fixtures in a viser scene, its compiled controller run live.

Scene nodes (names are stable; tests and scripts read them)::

    /robot                 the robot; /robot/link_<k> its parts, /robot/joints the joint origins
    /frames/<frame>        each task frame (axes) with /frames/<frame>/tool_axis and a label
    /fixtures/<key>        each constraint (key ``c<k>_<primitive>[_<frame>]``, k its index in the task)
                           with its shapes (/point, /polytope, /bound, /tube, /curve, /plane, ...) and /label
    /hand                  the user's hand: transform controls (live mode)
    /params/<param>        a gizmo per editable point, line, plane or pose param (live mode)
    /trace                 the tool's path, coloured by its error (replay mode)
    /teleop/ghost          a teleoperated task's goal (the scaled master's command), /teleop/force its haptic force

The viewer is assembled from its rooms: the scene (:mod:`vfdsl.view.scene`), the panel (:mod:`~vfdsl.view.panel`),
the params' gizmos (:mod:`~vfdsl.view.gizmos`), the live loop with the hand (:mod:`~vfdsl.view.live`), the
replay player (:mod:`~vfdsl.view.player`), a procedure's phase and buttons (:mod:`~vfdsl.view.procedure`) and a
teleoperated task's master, ghost and haptic arrow (:mod:`~vfdsl.view.teleop`);
each works on the viewer's one state, under its lock.
"""

from __future__ import annotations

import contextlib
import io
import threading

import numpy as np
import viser

from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus
from vfdsl.sim.geometry import Scene
from vfdsl.view.gizmos import ParamGizmos
from vfdsl.view.live import LiveLoop, control_period, hand_model
from vfdsl.view.options import free_port
from vfdsl.view.panel import Panel
from vfdsl.view.player import ReplayPlayer
from vfdsl.view.procedure import ProcedurePanel
from vfdsl.view.robot import RobotDrawing
from vfdsl.view.scene import SceneDrawing
from vfdsl.view.teleop import TeleopView


class Viewer(SceneDrawing, Panel, ParamGizmos, LiveLoop, ReplayPlayer, ProcedurePanel, TeleopView):
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
        self.phase, self.monitors, self.transition = None, {}, None      # a procedure's (vfdsl.view.procedure)
        self._press_left: dict[str, int] = {}
        self._hold_boxes: dict = {}
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

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()

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
            self._reset_param_fields()
            self.reset_procedure()
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
                    "message": self.message, "readout": self.readout,
                    "phase": self.phase, "monitors": dict(self.monitors), "transition": self.transition,
                    "pressed": sorted(n for n, left in self._press_left.items() if left > 0)}

    # ------------------------------------------------------------------------------------ building
    def _build(self) -> None:
        self._build_scene()
        self._static_step()
        self._build_gui()
        self._draw_state()
        self._draw_fixtures(force=True)
        if self.hand is not None:
            self._add_hand()
            self._place_param_gizmos()
        if self.replay is not None:
            self._build_replay()
        self._camera()

    def _draw_state(self) -> None:
        """The robot and frames at the current q, a teleoperated task's ghost and force, and the status line."""
        self._draw_robot()
        self._draw_teleop()
        self._write_status()
