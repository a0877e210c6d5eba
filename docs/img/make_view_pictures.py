"""Pictures of `vfdsl view` for docs/view.md and the README, taken by headless Chromium.

    python docs/img/make_view_pictures.py          # writes view_*.png next to this file (about 30 s each)

Each picture is the viewer of `vfdsl view TASK` (vfdsl.view.app.Viewer), driven here by a scripted hand
before the picture is taken (vfdsl.view.command.take_picture, what `vfdsl view --screenshot` uses):

- experiment A: the hand is held 10 mm ahead of the tip along the curve's tangent for 3 s, as a user
  dragging the handle along the curve would: the tip slides along the curve, the shaft follows its copy;
- experiment B: the hand on the shaft is held 10 mm to the side, around the cone, for 2 s: the tool turns
  around its cone while the tip stays on the pivot;
- a replay of experiment A: a 6 s run recorded here with the same controller and a hand pushing 5 N along
  the tangent, written as a trace CSV (columns t, q[i], tip_error_m: the format docs/view.md describes),
  replayed with `--replay` and shown at t = 5 s, its tip trace coloured by the distance to the curve
  (tolerances to scale here, so that the tube does not hide the trace).

Tolerances are drawn 1000 times larger (magnify 1000): the paper's 1 um tolerances are invisible to scale.
The handles are hidden in the pictures, as with --screenshot.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.sim.geometry import Curve, Scene
from vfdsl.view import replay
from vfdsl.view.app import Viewer
from vfdsl.view.command import take_picture
from vfdsl.view.options import free_port

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
TASK_A = REPO / "tasks" / "paper_a_follow_curve.vf"
TASK_B = REPO / "tasks" / "paper_b_virtual_rcm.vf"
MAGNIFY = 1000.0


def tangent_at(task, position) -> np.ndarray:
    """The unit tangent (world) of experiment A's curve at the point closest to ``position``."""
    scene = Scene(task)
    R, t = scene.to_world("path")
    curve = Curve(scene.values["path"])
    s, distance = curve.closest(((position - t) @ R)[None])
    return R @ curve.tangent(s[0]).ravel(), float(distance[0])


def hide_handles(viewer: Viewer) -> None:
    for name, node in viewer.nodes.items():
        if name == "/hand" or name.startswith("/params/"):
            node.visible = False


def save(viewer: Viewer, name: str) -> None:
    hide_handles(viewer)
    (HERE / name).write_bytes(take_picture(viewer, 1280, 800))
    print(f"wrote docs/img/{name}")


def paper_a() -> None:
    task = vfdsl.load(TASK_A)
    viewer = Viewer(task, vfdsl.compile(task), port=free_port(), magnify=MAGNIFY)
    try:
        for _ in range(int(3.0 / viewer.period)):
            tangent, _ = tangent_at(task, viewer.frames["tip"].position)
            viewer.push(0.010 * tangent)
            viewer.tick(draw=False)
        viewer.tick(draw=True)
        viewer._camera(direction=(0.25, -1.0, 1.4), distance=1.6)
        save(viewer, "view_paper_a.png")
    finally:
        viewer.close()


def paper_b() -> None:
    task = vfdsl.load(TASK_B)
    viewer = Viewer(task, vfdsl.compile(task), port=free_port(), magnify=MAGNIFY)
    try:
        axis = np.asarray(task.param("axis").value.xyz)
        for _ in range(int(2.0 / viewer.period)):
            tool = viewer.frames["tip"].tool_axis
            around = np.cross(axis, tool)                    # the way around the cone
            viewer.push(0.010 * around / np.linalg.norm(around))
            viewer.tick(draw=False)
        viewer.tick(draw=True)
        viewer._camera(direction=(0.9, -1.0, 0.6), distance=1.3)
        save(viewer, "view_paper_b.png")
    finally:
        viewer.close()


def record_paper_a(path: Path, seconds: float = 6.0) -> None:
    """A run of experiment A, a hand pushing 5 N along the curve's tangent: columns t, q[i], tip_error_m."""
    task = vfdsl.load(TASK_A)
    ctrl = vfdsl.compile(task)
    q = task.start.copy()
    rows = []
    for k in range(int(seconds / ctrl.default_dt) + 1):
        tangent, error = tangent_at(task, ctrl.frames(q)["tip"].position)
        rows.append([k * ctrl.default_dt, *q, error])
        q = q + ctrl.step(q, {"f": 5.0 * tangent})
    header = "t," + ",".join(f"q[{i}]" for i in range(len(q))) + ",tip_error_m"
    np.savetxt(path, np.array(rows), delimiter=",", header=header, comments="", fmt="%.9g")


def paper_a_replay() -> None:
    task = vfdsl.load(TASK_A)
    ctrl = vfdsl.compile(task)
    with tempfile.TemporaryDirectory() as scratch:
        path = Path(scratch) / "paper_a_run.csv"
        record_paper_a(path)
        trace = replay.read(path, Robot.load("shr7").joint_names)
    viewer = Viewer(task, ctrl, port=free_port(), replay=trace)           # to scale: the tube would hide the trace
    try:
        viewer.show_time(5.0)
        viewer._camera(direction=(0.25, -1.0, 1.4), distance=1.6)
        save(viewer, "view_paper_a_replay.png")
    finally:
        viewer.close()


if __name__ == "__main__":
    paper_a()
    paper_b()
    paper_a_replay()
