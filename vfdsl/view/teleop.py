"""A teleoperated task in the viewer: the hand's transform controls are the master, the master's command is a
ghost (where the scaled master puts the tool: Controller.teleop's goal) and the haptic force an arrow at the tool.

The master's pose is the controls' pose relative to where they started (the teleop frame's start pose), through the
camera: m = [R_c' (p - p_0); rpy(R_c' R R_0' R_c)], so that dragging the controls 10 mm moves the master 10 mm and
the tool scale x 10 mm. Scene nodes: /teleop/ghost (a sphere at the goal) and /teleop/force (a segment from the
teleop frame's origin along the force, FORCE_LENGTH per newton).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfdsl.compiler.geometry import rotation, rpy_of
from vfdsl.ir import model as ir
from vfdsl.objectives.haptics import teleop_terms

FORCE_LENGTH = 0.01          # m per N of the haptic arrow
GHOST_RADIUS = 0.002         # m


@dataclass
class MasterModel:
    """The master a teleop term reads, moved by the hand's controls (the interface of live.HandModel)."""

    input: ir.InputDecl
    frame: str
    camera: np.ndarray                     # R_c: world <- master base
    origin: tuple[np.ndarray, np.ndarray] | None = None     # the controls' start pose (p_0, R_0), set at the first rest
    linear: bool = True
    angular: bool = True
    lever: float = 0.0

    def rest(self, pose) -> tuple[np.ndarray, np.ndarray]:
        """Where the controls start: the teleop frame's pose the first time (then fixed: the master's origin)."""
        if self.origin is None:
            self.origin = (np.array(pose.position, dtype=float), np.array(pose.rotation, dtype=float))
        return self.origin

    def value(self, pose, position, rotation_matrix) -> np.ndarray:
        p0, R0 = self.rest(pose)
        R_c = self.camera
        turn = R_c.T @ np.asarray(rotation_matrix) @ R0.T @ R_c
        return np.concatenate([R_c.T @ (np.asarray(position, dtype=float) - p0), rpy_of(turn)])


def master_model(task: ir.Task) -> MasterModel | None:
    """The master of the task's first teleop term (None without one)."""
    terms = teleop_terms(task)
    if not terms:
        return None
    o = terms[0]
    camera = o.args["camera"]
    value = camera.value if isinstance(camera, ir.Const) else task.param(camera.name).value
    return MasterModel(task.input(o.args["master"].name), o.args["frame"].name, rotation(value.rpy))


def teleop_line(out) -> str:
    """The status line of a teleoperated tick: following or clutched, the ghost's lead, the force, what acted."""
    if out is None:
        return ""
    lead = np.linalg.norm(out.goal - out.setpoint[:3]) * 1e3
    state = "following" if out.following else "clutched: the arm holds"
    acted = f" · acting: {'; '.join(out.acting)}" if out.acting else ""
    return f"master {state} · ghost {lead:.2f} mm ahead · haptic {np.linalg.norm(out.force):.2f} N{acted}"


class TeleopView:
    """The viewer's ghost and haptic arrow (:meth:`_draw_teleop`), redrawn with the state."""

    def _draw_teleop(self) -> None:
        out = getattr(self.ctrl, "teleop", None)
        if out is None or not isinstance(self.hand, MasterModel):
            return
        scene = self.server.scene
        tip = self.frames[self.hand.frame].position
        segment = np.array([[tip, tip + FORCE_LENGTH * out.force]], dtype=np.float32)
        if "/teleop/ghost" not in self.nodes:
            self.nodes["/teleop/ghost"] = scene.add_icosphere("/teleop/ghost", radius=GHOST_RADIUS,
                                                             color=(80, 160, 255), opacity=0.5, position=out.goal)
            self.nodes["/teleop/force"] = scene.add_line_segments("/teleop/force", segment, colors=(255, 120, 0),
                                                                 thickness=4.0, thickness_units="screen")
        else:
            self.nodes["/teleop/ghost"].position = out.goal
            self.nodes["/teleop/force"].points = segment

