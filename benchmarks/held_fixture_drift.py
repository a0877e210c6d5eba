"""A hard fixture that holds, while another one comes back from outside: how far the one that held is pushed off.

tasks/lecture_remote_center.vf (the Panda's tool through a port, within 0.5 mm, 10 ms ticks) with a second hard
fixture added, ``require tip cone(axis, 15)``, its axis placed 20 to 168 deg from the tool, so that the cone is 5 to
153 deg outside. Hands off. Each tick that cannot bring the tool into the cone is least violation: its (A) keeps
every row no worse than at rest, to first order, while the joints run at their speed limits. Prints, per placement,
the port's largest true error (its distance to the tool axis, from Pinocchio's kinematics) over 400 ticks, the
least-violation ticks, and the errors at the end. For comparison, the same task without the cone driven by a fast
joystick (2 rad/s about the port: phase 1 alone, the rows hold each tick to first order and bring the port back the
tick after).

    python benchmarks/held_fixture_drift.py [native|interpreted]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.kinematics.robot import Robot

ROOT = Path(__file__).resolve().parent.parent
TASK = ROOT / "tasks" / "lecture_remote_center.vf"
PORT = np.array([306.890567, 0, 546.882052]) * 1e-3        # the scene's port (tasks/lecture_remote_center.yaml)
ROBOT = Robot.load("panda7")
TICKS = 400


def _errors(q, axis):
    """(the port's distance to the tool axis in mm, the tool's angle to ``axis`` in deg)."""
    p, R = ROBOT.frame_pose(q, "tool_tip")
    z, v = R[:, 2], PORT - p
    port = np.linalg.norm(v - (v @ z) * z) * 1e3
    return port, np.degrees(np.arccos(np.clip(z @ axis, -1.0, 1.0))) if axis is not None else float("nan")


def _run(folder: Path, backend: str, cone_deg: float | None, stick) -> str:
    source = TASK.read_text()
    axis = None
    if cone_deg is not None:
        a = np.radians(cone_deg)
        axis = np.array([np.sin(a), 0.0, -np.cos(a)])      # the tool points down at the start
        source += f"require tip cone([{axis[0]:.9f}, 0, {axis[2]:.9f}], 15)\n"
    (folder / "t.vf").write_text(source)
    (folder / "t.yaml").write_text(TASK.with_suffix(".yaml").read_text())
    task = vfdsl.load(folder / "t.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    q = np.array(task.start, dtype=float)
    worst, least = 0.0, 0
    for _ in range(TICKS):
        q = q + ctrl.step(q, {"stick": stick})
        least += int(ctrl.status) & 1
        port, angle = _errors(q, axis)
        worst = max(worst, port)
    where = f"cone axis {cone_deg:5.0f} deg from the tool" if cone_deg is not None else "no cone, fast joystick    "
    return (f"{where}  port error max {worst:6.3f} mm  least-violation ticks {least:3d}/{TICKS}  "
            f"end: port {port:.3f} mm" + (f", cone {angle:.2f} deg" if axis is not None else ""))


def main(backend: str = "native") -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"a port held within 0.5 mm while a cone (15 deg) comes back, {TICKS} ticks of 10 ms ({backend})")
        for cone_deg in (20, 30, 45, 90, 168):
            print(_run(folder, backend, cone_deg, np.zeros(6)))
        print(_run(folder, backend, None, np.array([0, 0, 0, 2.0, 0, 0])))


if __name__ == "__main__":
    main(*sys.argv[1:2])
