"""Priority levels against an independent solution, and tracking that only fixtures and limits may cut.

- every level at its optimum: at random states of every example task (and variants with `centering`, a soft
  constraint in the first and in a lower level), the step's answer is compared, level by level, with the
  levels solved in turn by DAQP's Python package over the null space of the levels above
  (tests/levels_reference.py); a level of the step costing more than the reference's, where the two differ by
  more than the band, is a level not solved to its optimum. VFDSL_LEVEL_STATES (default 40) sets the number
  of states; 200 is the figure in docs/runtime.md;
- a push is not lost: a tool held by `passes_through(port)` a few mm above its tip on both shipped robots, a
  2 N sideways force at 1 mm/s/N for 1 s: the tip moves as far as the same closed loop driven by the
  reference solution (within 1 % of the commanded motion), and >= 95 % of the command at 4 mm on panda7; a
  torque turns the tool about the port by the commanded angle.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import TASKS_DIR, port_task
from levels_reference import first_worse, level_data, robust, worse
from test_priorities import _with_lines

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus

pytestmark = pytest.mark.slow

STATES = int(os.environ.get("VFDSL_LEVEL_STATES", 40))
WORSE = 2.5e-4      # a dropped level costs 5e-4 (paper_a) to 0.1 (lecture_remote_center) more, relative
WORSE_LAST = 1e-3
"""Measured at 200 states (VFDSL_LEVEL_STATES=200), both paths: every level within 1e-4 of the reference's cost on
every example task but lecture_remote_center, where DAQP holds each level's rows to its tolerance (~1e-9 per tick)
rather than exactly as the reference does: its tracked level with a soft constraint 1.6e-4 above (one state), and
its last level, the smallest motion among those the tracked levels leave free (damping; damping and centering),
up to 7.7e-4 above (3 states): along a direction the tracked rows barely constrain, that motion moves by up to
2.8e-5 rad per tick while the tracked levels agree to 6e-9."""
VARIANTS = {"centering": "minimize centering() weight 1e-2",
            "soft_level1": "require tip speed(5 mm/s) soft weight 100",
            "soft_level2": "require tip speed(5 mm/s) soft weight 100 priority 2"}


def _cases():
    for path in sorted(TASKS_DIR.glob("*.vf")):
        yield path.stem, None
    for name, lines in VARIANTS.items():
        yield f"lecture_remote_center+{name}", lines
    yield "paper_a_follow_curve+centering", VARIANTS["centering"]


@pytest.mark.parametrize("backend", ["interpreted", "native"])
@pytest.mark.parametrize("case", list(_cases()), ids=lambda c: c[0])
def test_every_level_is_at_its_optimum(tmp_path, case, backend):
    name, lines = case
    path = TASKS_DIR / f"{name.split('+')[0]}.vf"
    task = vfdsl.load(_with_lines(tmp_path, path, lines) if lines else path)
    ctrl = vfdsl.compile(task, backend=backend)
    robot = Robot.load(task.robots[0].urdf)
    rng = np.random.default_rng(11)
    compared = 0
    for _ in range(STATES):
        q = np.clip(task.start + rng.normal(scale=1e-5, size=robot.nq), robot.lower, robot.upper)
        inputs = {k: rng.normal(scale=2.0, size=s) for k, s in ctrl.input_sizes.items()}
        ctrl.step(q, inputs)
        if ctrl.status != StepStatus.OPTIMAL:
            continue
        data = level_data(ctrl, q, inputs)
        x_ref, ok = robust(*data)
        if not ok:         # the reference's own solver failed (it has no fallback): nothing to compare
            continue
        compared += 1
        level, excess = first_worse(data[0], ctrl._runner.x, x_ref)
        assert excess <= (WORSE_LAST if level == len(data[0]) - 1 else WORSE), (q.tolist(), inputs, level)
    assert compared >= STATES // 2, f"only {compared} of {STATES} states compared"


def _side(up):
    side = np.cross(up, [1.0, 0, 0]) if abs(up[0]) < 0.9 else np.cross(up, [0, 1.0, 0])
    return side / np.linalg.norm(side)


def _push(ctrl, task, inputs, ticks, reference=False):
    q = task.start.copy()
    for _ in range(ticks):
        if reference:
            x, ok = robust(*level_data(ctrl, q, inputs))
            assert ok
            q = q + x[:ctrl.nq]
        else:
            q = q + ctrl.step(q, inputs)
            assert ctrl.status == StepStatus.OPTIMAL
    return q


@pytest.mark.parametrize("robot_name", ["panda7", "shr7"])
@pytest.mark.parametrize("distance_mm", [2, 4, 12, 30, 100])
def test_a_push_about_a_close_port_is_not_lost(tmp_path, robot_name, distance_mm):
    """2 N sideways at 1 mm/s/N for 1 s (2 mm asked): the tip moves as far as the reference loop makes it (what
    the fixture and the speed limits allow), within 1 % of the command; >= 95 % at 4 mm on panda7."""
    task, robot, p0, _, up = port_task(tmp_path, robot_name, distance_mm * 1e-3)
    ctrl = vfdsl.compile(task, backend="interpreted")
    side = _side(up)
    inputs = {"hand": 2.0 * side}
    moved = [float((robot.frame_pose(q, "tool_tip")[0] - p0) @ side) / 2e-3
             for q in (_push(ctrl, task, inputs, 100), _push(ctrl, task, inputs, 100, reference=True))]
    print(f"{robot_name} port {distance_mm} mm: step {moved[0]:.1%}, reference {moved[1]:.1%} of the command")
    assert moved[0] >= moved[1] - 0.01, moved
    if distance_mm >= 4 and robot_name == "panda7":
        assert moved[0] >= 0.95


@pytest.mark.parametrize("robot_name", ["panda7", "shr7"])
def test_a_torque_turns_the_tool_about_the_port(tmp_path, robot_name):
    """2 N mm about a sideways axis at 1 deg/s/Nmm for 1 s: the tool turns 2 deg (within 1 %) about the port."""
    task, robot, p0, R0, up = port_task(tmp_path, robot_name, 4e-3, torque=True)
    ctrl = vfdsl.compile(task, backend="interpreted")
    q = _push(ctrl, task, {"hand": 2e-3 * _side(up)}, 100)
    R = robot.frame_pose(q, "tool_tip")[1]
    angle = np.degrees(np.arccos(np.clip((np.trace(R0.T @ R) - 1) / 2, -1, 1)))
    assert angle == pytest.approx(2.0, rel=0.01)


def test_problem_gives_each_level(tmp_path):
    """`Controller.problem()` gives each level's rows, targets and cost, and solving those levels in turn (with the
    rows and bounds it gives) reproduces `step()`: the issue's port 4 mm above the tip, 2 mm/s asked."""
    task, robot, p0, _, up = port_task(tmp_path, "panda7", 4e-3)
    ctrl = vfdsl.compile(task, backend="interpreted")
    inputs = {"hand": 2.0 * _side(up)}
    qp = ctrl.problem(task.start, inputs)
    assert [level.terms for level in qp.levels] == [["track(tip) linear"], ["track(tip) angular"], ["damping()"]]
    np.testing.assert_allclose(sum(level.P for level in qp.levels), qp.P + 2e-9 * np.eye(qp.P.shape[0]), atol=1e-15)
    n = qp.P.shape[0]
    x_ref, ok = robust([(lv.P, lv.g, lv.R) for lv in qp.levels], qp.A[n:], qp.lb[n:], qp.ub[n:], qp.lb[:n], qp.ub[:n])
    dq = ctrl.step(task.start, inputs)
    assert ok and worse([(lv.P, lv.g, lv.R) for lv in qp.levels], ctrl._runner.x, x_ref) <= WORSE
    assert np.linalg.norm(qp.levels[0].R @ dq) / np.sqrt(2) / 0.01 == pytest.approx(2e-3, rel=0.01)   # 2 mm/s (R: sqrt(2 w) J)
    other = vfdsl.compile(vfdsl.load(TASKS_DIR / "lecture_steady_direction.vf"), backend="interpreted")
    levels = other.problem(other.task.start, {k: np.zeros(s) for k, s in other.input_sizes.items()}).levels
    assert [level.terms for level in levels] == [["distance(tip)", "direction_change(tip)"], ["damping()"]]


def test_tracking_readout_says_what_holds_the_tip(tmp_path):
    """`ctrl.tracking()`: with the port 2 mm above the tip on shr7 the push is held (63 %) and the readout names
    the port's facet; 60 mm away it follows and nothing is named."""
    for distance, held in ((2e-3, True), (60e-3, False)):
        folder = tmp_path / f"port_{distance * 1e3:.0f}mm"
        folder.mkdir()
        task, _, _, _, up = port_task(folder, "shr7", distance)
        ctrl = vfdsl.compile(task, backend="interpreted")
        inputs = {"hand": 2.0 * _side(up)}
        q = _push(ctrl, task, inputs, 60)
        linear = next(t for t in ctrl.tracking(q, inputs) if t.term == "track(tip) linear")
        np.testing.assert_allclose(linear.commanded, 2e-3 * _side(up))
        if held:
            assert 0.5 < linear.fraction < 0.9 and any("passes_through(tip)" in label for label in linear.limits)
            assert "held by " in str(linear) and "passes_through(tip) facet" in str(linear)
        else:
            assert linear.fraction >= 0.99 and linear.limits == []
