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

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from test_held_fixture import cone_task, errors  # noqa: E402

import vfdsl  # noqa: E402

TICKS = 400


def _run(folder: Path, backend: str, cone_deg: float | None, stick) -> str:
    task, axis = cone_task(folder, cone_deg)
    ctrl = vfdsl.compile(task, backend=backend)
    q = np.array(task.start, dtype=float)
    worst, least = 0.0, 0
    for _ in range(TICKS):
        q = q + ctrl.step(q, {"stick": stick})
        least += int(ctrl.status) & 1
        port, angle = errors(q, axis)
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
