"""The needle insertion example (tasks/needle_insertion.vf): a simulated hand pushes the needle along and across
its planned line; the tip is measured with Pinocchio (not the compiler) against the line, direction and stop
plane computed here with numpy from the scene's entry and target points."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus

compile_task = partial(vfdsl.compile, backend="interpreted")

EPS_LINE = 0.5e-3                      # along ... within 0.5 mm, octagon
EPS_ANGLE = np.radians(1.0)            # keeps_direction ... within 1 deg, octagon
LINE_BOUND = EPS_LINE / np.cos(np.pi / 8)          # the octagon's circumradius
ANGLE_BOUND = EPS_ANGLE / np.cos(np.pi / 8)
MODEL_ERROR = 5e-6                     # first-order (one tick) error of the rows, m or rad
STOP_TOLERANCE = 5e-6                  # how far past the stop plane a tick may end (first-order model)


def _geometry(entry, target):
    d = (target - entry) / np.linalg.norm(target - entry)
    return d


def _measure(robot, q, entry, target):
    """Distance of the tip to the line, angle of the needle (-tool axis) to the line, height above the stop
    plane (toward the entry), distance to the target."""
    p, R = robot.frame_pose(q, "tool_tip")
    d = _geometry(entry, target)
    needle = -R[:, 2]
    return (np.linalg.norm(np.cross(p - entry, d)), np.arccos(np.clip(needle @ d, -1.0, 1.0)),
            (p - target) @ -d, np.linalg.norm(p - target))


def _push(d, k):
    """5 N along the needle and up to 3 N across it, turning."""
    across = np.cross(d, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    other = np.cross(d, across)
    return 5.0 * d + 3.0 * (np.cos(0.05 * k) * across + np.sin(0.05 * k) * other)


@pytest.mark.slow
def test_needle_reaches_the_target_on_its_line_and_stops_there():
    task = vfdsl.load(TASKS_DIR / "needle_insertion.vf")
    ctrl = compile_task(task)
    robot = Robot.load("shr7")
    entry, target = (np.array(task.param(n).value.xyz) for n in ("entry", "target"))
    d = _geometry(entry, target)
    q = task.start.copy()
    start = _measure(robot, q, entry, target)
    assert start[0] < 1e-8 and start[1] < 1e-6 and start[3] == pytest.approx(np.linalg.norm(target - entry))
    rows, statuses = [], set()
    for k in range(1500):
        q = q + ctrl.step(q, {"hand": _push(d, k)})
        statuses.add(ctrl.status)
        rows.append(_measure(robot, q, entry, target))
    distance, angle, height, to_target = np.array(rows).T
    assert statuses == {StepStatus.OPTIMAL}
    assert distance.max() <= LINE_BOUND + MODEL_ERROR
    assert distance.max() > 0.5 * EPS_LINE, "the push across the needle should press the tip against the bound"
    assert angle.max() <= ANGLE_BOUND + MODEL_ERROR
    assert height.min() >= -STOP_TOLERANCE
    assert height[-1] <= 1e-5, "the push should bring the tip onto the stop plane"
    assert to_target[-1] <= LINE_BOUND + 1e-4, "the push should bring the tip to the target"


@pytest.mark.slow
def test_the_fixture_follows_a_target_moved_at_run_time():
    """The target moves 6 mm sideways over 3 s (0.02 mm a tick) while the hand pushes: the line, the direction
    and the stop plane follow it, every tick."""
    task = vfdsl.load(TASKS_DIR / "needle_insertion.vf")
    ctrl = compile_task(task)
    robot = Robot.load("shr7")
    entry, target = (np.array(task.param(n).value.xyz) for n in ("entry", "target"))
    moved = target + np.array([0.0, 6e-3, 0.0])
    q = task.start.copy()
    rows = []
    for k in range(1200):
        now = target + (moved - target) * min(1.0, k / 300)
        q = q + ctrl.step(q, {"hand": _push(_geometry(entry, now), k)}, params={"target": now})
        assert ctrl.status == StepStatus.OPTIMAL
        rows.append(_measure(robot, q, entry, now))
    distance, angle, height, to_target = np.array(rows).T
    assert distance.max() <= LINE_BOUND + MODEL_ERROR
    assert angle.max() <= ANGLE_BOUND + MODEL_ERROR
    assert height.min() >= -STOP_TOLERANCE
    assert to_target[-1] <= LINE_BOUND + 1e-4, "the tip should reach the moved target"
    assert _measure(robot, q, entry, target)[0] > 1e-3, "the tip should have left the old line"


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_a_target_moved_onto_the_entry_is_refused_before_anything_moves(backend):
    """With target = entry the line, the direction and the stop plane have no direction: every path of step
    refuses the params with an error at the expression, and the controller works on afterwards."""
    task = vfdsl.load(TASKS_DIR / "needle_insertion.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    entry = task.param("entry").value.xyz
    q = task.start.copy()
    hand = {"hand": [0.0, 0.0, 1.0]}
    for params in ({"target": entry}, {"target": np.add(entry, 1e-10)},
                   {"entry": task.param("target").value.xyz}):
        with pytest.raises(vfdsl.VfError) as info:
            ctrl.step(q, hand, params=params)
        err = info.value
        assert "has no direction" in err.message and err.pos.line == 20 and err.pos.column == 22
    with pytest.raises(vfdsl.VfError, match="has no direction"):
        ctrl.problem(q, hand, params={"target": entry})
    assert np.all(np.isfinite(ctrl.step(q, hand)))
    assert np.all(np.isfinite(ctrl.step(q, hand, params={"target": np.add(entry, [0.0, 0.0, -0.01])})))


def test_a_scene_with_the_target_on_the_entry_is_refused_at_load(tasks_copy):
    scene = tasks_copy / "needle_insertion.yaml"
    scene.write_text(scene.read_text().replace("target: [20, -5, 235]", "target: [10, 5, 285]"))
    with pytest.raises(vfdsl.VfError) as info:
        vfdsl.load(tasks_copy / "needle_insertion.vf")
    assert "the two points of this line coincide" in info.value.message
    assert (info.value.pos.line, info.value.pos.column) == (20, 22)
