"""A keep-in fixture far on the wrong side: tasks/sinus_channel.vf with its stage shifted 19 mm sideways, so that the
tool's shaft is 15 mm outside the channel, and the hand pushing 10 N further out for 0.5 s (50 ticks of 10 ms).
Prints the true clearance of the shaft (brute force over the triangles) before and after, the ticks' statuses and
the fixtures ``violations()`` named.

    python benchmarks/far_outside.py [native|interpreted]

Before the mesh query kept the nearest feature of an end on the forbidden side, every tick was OPTIMAL with no
violation and the tool followed the hand out (clearance -15 -> -20 mm); now every tick is LEAST_VIOLATION with
inside_mesh named, and the tool comes back at its 20 mm/s speed limit (-15 -> -5 mm).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.load import read_mesh

ROOT = Path(__file__).resolve().parent.parent


def main(backend: str = "native") -> None:
    task = vfdsl.load(ROOT / "tasks" / "sinus_channel.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    robot = Robot.load("shr7")
    mesh = read_mesh(ROOT / "tasks" / "anatomy" / "channel.stl", 1e-3)

    def clearance(q) -> float:
        p, R = robot.frame_pose(q, "tool_tip")
        return brute.signed_clearance(p, p + R[:, 2] * 0.03, 0.001, mesh.vertices, mesh.triangles, True)

    q = np.array(task.start, dtype=float)
    q[0] -= 0.019
    before, statuses, named = clearance(q), [], set()
    for _ in range(50):
        q = q + ctrl.step(q, {"f": [-10.0, 0.0, 0.0]}, None, 0.01)
        statuses.append(int(ctrl.status))
        named |= {v.label.primitive for v in ctrl.violations()}
    print(f"clearance {before * 1e3:.2f} mm -> {clearance(q) * 1e3:.2f} mm after 50 ticks; "
          f"statuses {sorted(set(statuses))}; least-violation ticks {sum(s & 1 for s in statuses)}/50; "
          f"named {sorted(named)}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
