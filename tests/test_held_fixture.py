"""A hard fixture that holds stays held while another one comes back from outside.

lecture_remote_center (the Panda's tool through a port within 0.5 mm, 10 ms ticks) with a second hard fixture, a
15 deg cone whose axis is 20, 45 or 90 deg from the tool: the cone cannot be reached in one tick, so the ticks are
least violation, every joint at its speed limit. The port's true error (its distance to the tool axis, from
Pinocchio's kinematics) is checked tick by tick, on both paths.

Phase 2's (A) keeps every row no worse than at rest to first order; the first tick's second-order remainder takes the
port 0.78 mm past its tolerance (1.276 mm). Before each group's penalty was weighed against its own violation at
rest, that remainder was never brought back (the port, then violated at rest, was only kept no worse, and its
millimetres weighed as little as the cone's radians): the errors added up tick after tick, to 4.84 mm for the cone
at 45 deg and 6.16 mm at 90 deg (benchmarks/held_fixture_drift.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.kinematics.robot import Robot

PORT = np.array([306.890567, 0, 546.882052]) * 1e-3        # tasks/lecture_remote_center.yaml's port
ROBOT = Robot.load("panda7")
POLYTOPE = 0.5 / np.cos(np.pi / 8)                         # the port's octagon (resolution 8) reaches 0.541 mm


def _errors(q, axis):
    p, R = ROBOT.frame_pose(q, "tool_tip")
    z, v = R[:, 2], PORT - p
    return np.linalg.norm(v - (v @ z) * z) * 1e3, np.degrees(np.arccos(np.clip(z @ axis, -1.0, 1.0)))


@pytest.mark.parametrize("backend", ["native", "interpreted"])
@pytest.mark.parametrize("cone_deg", [20, 45, 90])
def test_a_held_port_is_not_pushed_off_while_a_cone_comes_back(tmp_path, cone_deg, backend):
    a = np.radians(cone_deg)
    axis = np.array([np.sin(a), 0.0, -np.cos(a)])          # the tool points down at the start
    task_file = TASKS_DIR / "lecture_remote_center.vf"
    (tmp_path / "t.vf").write_text(task_file.read_text()
                                   + f"require tip cone([{axis[0]:.9f}, 0, {axis[2]:.9f}], 15)\n")
    (tmp_path / "t.yaml").write_text(task_file.with_suffix(".yaml").read_text())
    task = vfdsl.load(tmp_path / "t.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    q = np.array(task.start, dtype=float)
    assert _errors(q, axis)[0] < 1e-3
    ports, least = [], 0
    for _ in range(150):
        q = q + ctrl.step(q, {"stick": np.zeros(6)})
        least += int(ctrl.status) & 1
        ports.append(_errors(q, axis)[0])
    ports = np.array(ports)
    assert least >= 1                                        # the cone was out of reach in one tick
    assert ports.max() < 1.3, ports.max()                   # the first tick's second-order remainder, and no more
    outside = ports[:-1] > POLYTOPE + 1e-6
    assert np.all(ports[1:][outside] <= ports[:-1][outside] + 1e-6), "the port's error grew while it was off"
    port, cone = _errors(q, axis)
    assert port <= POLYTOPE + 1e-6 and cone <= 15.1, (port, cone)   # both hold at the end
