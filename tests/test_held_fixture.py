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

import tempfile
from pathlib import Path

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.kinematics.robot import Robot

PORT = np.array([306.890567, 0, 546.882052]) * 1e-3        # tasks/lecture_remote_center.yaml's port
ROBOT = Robot.load("panda7")
POLYTOPE = 0.5 / np.cos(np.pi / 8)                         # the port's octagon (resolution 8) reaches 0.541 mm
TASK = TASKS_DIR / "lecture_remote_center.vf"


def cone_task(folder, cone_deg: float | None):
    """(task, cone axis): lecture_remote_center with ``require tip cone(axis, 15)`` added, its axis ``cone_deg``
    from the tool at the start (the tool points down); None: the task alone (axis None)."""
    source, axis = TASK.read_text(), None
    if cone_deg is not None:
        a = np.radians(cone_deg)
        axis = np.array([np.sin(a), 0.0, -np.cos(a)])
        source += f"require tip cone([{axis[0]:.9f}, 0, {axis[2]:.9f}], 15)\n"
    (folder / "t.vf").write_text(source)
    (folder / "t.yaml").write_text(TASK.with_suffix(".yaml").read_text())
    return vfdsl.load(folder / "t.vf"), axis


def errors(q, axis):
    """(the port's distance to the tool axis in mm, the tool's angle to ``axis`` in deg, NaN without an axis)."""
    p, R = ROBOT.frame_pose(q, "tool_tip")
    z, v = R[:, 2], PORT - p
    port = np.linalg.norm(v - (v @ z) * z) * 1e3
    return port, np.degrees(np.arccos(np.clip(z @ axis, -1.0, 1.0))) if axis is not None else float("nan")


@pytest.mark.parametrize("backend", ["native", "interpreted"])
@pytest.mark.parametrize("cone_deg", [20, 45, 90])
def test_a_held_port_is_not_pushed_off_while_a_cone_comes_back(tmp_path, cone_deg, backend):
    task, axis = cone_task(tmp_path, cone_deg)
    ctrl = vfdsl.compile(task, backend=backend)
    q = np.array(task.start, dtype=float)
    assert errors(q, axis)[0] < 1e-3
    ports, least = [], 0
    for _ in range(150):
        q = q + ctrl.step(q, {"stick": np.zeros(6)})
        least += int(ctrl.status) & 1
        ports.append(errors(q, axis)[0])
    ports = np.array(ports)
    assert least >= 1                                        # the cone was out of reach in one tick
    assert ports.max() < 1.3, ports.max()                   # the first tick's second-order remainder, and no more
    outside = ports[:-1] > POLYTOPE + 1e-6
    assert np.all(ports[1:][outside] <= ports[:-1][outside] + 1e-6), "the port's error grew while it was off"
    port, cone = errors(q, axis)
    assert port <= POLYTOPE + 1e-6 and cone <= 15.1, (port, cone)   # both hold at the end


def test_hands_off_the_tool_comes_to_rest_beside_a_port_and_a_cone_168_deg_off():
    """Hands off, the cone 168 deg from the tool: the motion stops, and a cone not reached is named. The cone's rows
    (eq. 13, on the whole rotation J_w dq) see a roll about the tool axis in their polygon's plane; with the polygon's
    phase from a fixed basis, once the port held the tool a facet off the cone every tick met that facet by rolling,
    OPTIMAL, nothing named, joint 7 turning 1.4e-4 rad a tick (0.8 deg/s) for as long as the task ran. The polygon's
    facet n/n now lies along delta_r, so the facets a roll could meet come in mirrored pairs (test_primitives)."""
    with tempfile.TemporaryDirectory() as folder:
        task, axis = cone_task(Path(folder), 168)
        ctrl = vfdsl.compile(task)
    q = np.array(task.start, dtype=float)
    for _ in range(500):
        q = q + ctrl.step(q, {"stick": np.zeros(6)})
    for _ in range(100):
        dq = ctrl.step(q, {"stick": np.zeros(6)})
        q = q + dq
        assert np.abs(dq).max() == 0.0, np.abs(dq).max()
        port, cone = errors(q, axis)
        assert port <= 0.55
        if ctrl.status & 1:
            assert {v.label.primitive for v in ctrl.violations()} >= {"cone"}
        else:
            assert cone <= 15.1
