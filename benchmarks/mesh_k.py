"""The number of rows K of a mesh fixture against the clearance it keeps, on tasks/sinus_channel.vf.

    python benchmarks/mesh_k.py

For K = 4, 8 and 16 (vfdsl.compiler.mesh_rows.K, set before compiling), the hand pushes the shaft into the
channel's wall in four directions (20 N along +x, -x, +y, -y, 2 N down) for 250 ticks each from the start; the
smallest clearance of the capsule over those ticks, by brute force over every triangle (vfdsl.mesh.brute). For
K = 8, also how many features the query's answer keeps within reach (over its three parts, after merging), at
every 5th tick: brute.features with room for all of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import vfdsl
import vfdsl.compiler.mesh_rows as mesh_rows
from vfdsl.check.kinematics import frame_pose
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.external import SIMILAR
from vfdsl.mesh.load import read_mesh

TASKS = Path(__file__).resolve().parent.parent / "tasks"
PUSHES = ([20, 0, -2], [-20, 0, -2], [0, 20, -2], [0, -20, -2])     # N
TICKS = 250
CUTOFF = 0.0015 + mesh_rows.REACH                                    # the example's radius + margin + reach


def main() -> None:
    channel = read_mesh(TASKS / "anatomy" / "channel.stl", 1e-3)
    for k in (4, 8, 16):
        mesh_rows.K = k
        task = vfdsl.load(TASKS / "sinus_channel.vf")
        robot = Robot.load(task.robots[0].urdf)
        ctrl = vfdsl.compile(task)
        least, kept = np.inf, []
        for push in PUSHES:
            q = task.start.copy()
            for tick in range(TICKS):
                q = q + ctrl.step(q, {"f": np.array(push, float)})
                a, b = (frame_pose(robot, task.frame(name), q)[0] for name in ("tip", "shaft"))
                least = min(least, brute.signed_clearance(a, b, 0.001, channel.vertices, channel.triangles, True))
                if k == 8 and tick % 5 == 0:
                    d = brute.features(a, b, channel.vertices, channel.triangles, CUTOFF, -1.0, 500, SIMILAR)[0]
                    kept.append(int(np.isfinite(d).sum()))
        print(f"K = {k}: smallest clearance {least * 1e3:.4f} mm (margin 0.5 mm)")
        if kept:
            print(f"  features kept within reach: max {max(kept)}, 99th percentile {np.percentile(kept, 99):.0f}, "
                  f"median {np.median(kept):.0f}")


if __name__ == "__main__":
    main()
