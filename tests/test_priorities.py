"""Objective semantics (rates, priority levels, `track` parts), measured in closed loop with Pinocchio.

- hands off: with zero input the tracked frames of every example task stay within 0.1 mm and 0.1 deg over 2 s,
  whatever weight the redundancy terms get, while `centering` still moves the joints toward their middles;
- the pivot push: a sideways push on lecture_remote_center.vf moves the tip by at least 80 % of the commanded
  admittance motion while the tool stays on its port;
- weights are independent of dt: the same push gives the same tip speed and the same soft-constraint
  penetration at 1 ms and 10 ms, and the penetration is the documented w_t v / (w k);
- a lower level never degrades a higher one, and the same term at level 1 does (so the check can fail).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.compiler.assemble import SOFT_RESTORE_RATE
from vfdsl.compiler.geometry import homogeneous
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot

pytestmark = pytest.mark.slow

DRIFT_LENGTH, DRIFT_ANGLE = 1e-4, math.radians(0.1)     # the bound: 0.1 mm and 0.1 deg over 2 s
HANDS_OFF_SECONDS = 2.0
EXAMPLES = sorted(TASKS_DIR.glob("*.vf"))


def _poses(task, q):
    robot = Robot.load(task.robots[0].urdf)
    return {f.name: robot.frame_pose(q, f.link, homogeneous(f.offset, f.rpy)) for f in task.frames}


def _rotation_angle(R0, R1) -> float:
    return math.acos(max(-1.0, min(1.0, (np.trace(R0.T @ R1) - 1) / 2)))


def _run(ctrl, task, q, seconds, inputs, dt=None):
    """q after ``seconds`` of q <- q + step(q, inputs(k)), and the trajectory."""
    dt = dt or task.scene.period
    trajectory = [q.copy()]
    for k in range(int(round(seconds / dt))):
        q = q + ctrl.step(q, inputs(k), dt=dt)
        trajectory.append(q.copy())
    return np.array(trajectory)


def _zero(task):
    return {d.name: np.zeros(d.size) for d in task.inputs}


def _drift(task, trajectory, frames):
    """Largest displacement and rotation of ``frames`` from their pose at the start of ``trajectory``."""
    start = _poses(task, trajectory[0])
    moved = turned = 0.0
    for q in trajectory[1:]:
        for name, (p, R) in _poses(task, q).items():
            if name in frames:
                moved = max(moved, float(np.linalg.norm(p - start[name][0])))
                turned = max(turned, _rotation_angle(start[name][1], R))
    return moved, turned


def _tracked_frames(task) -> set[str]:
    return {o.args["frame"].name for o in task.objectives if o.term in ("track", "distance", "direction_change")}


def _with_lines(tmp_path: Path, task_file: Path, lines: str) -> Path:
    """A copy of an example task (beside its scene, library and meshes) with ``lines`` appended."""
    text = task_file.read_text()
    if not any(line.startswith("scene ") for line in text.splitlines()) and task_file.with_suffix(".yaml").exists():
        text += f'\nscene "{task_file.with_suffix(".yaml").resolve()}"\n'
    text = text.replace('import "library/', f'import "{(task_file.parent / "library").resolve()}/')
    text = text.replace('= "anatomy/', f'= "{(task_file.parent / "anatomy").resolve()}/')       # mesh files
    text = text.replace('scene "', f'scene "{task_file.parent.resolve()}/').replace(
        f'scene "{task_file.parent.resolve()}//', 'scene "/')
    path = tmp_path / task_file.name
    path.write_text(text + "\n" + lines + "\n")
    return path


@pytest.mark.parametrize("task_file", EXAMPLES, ids=lambda p: p.stem)
@pytest.mark.parametrize("redundancy", ["", "minimize centering() weight 1e-3\nminimize damping() weight 1e3",
                                        "minimize centering() weight 1e6\nminimize damping() weight 1e-9"])
def test_hands_off_every_example_stays_still(tmp_path, task_file, redundancy):
    """Zero input for 2 s: every frame a term tracks stays within 0.1 mm (and a tracked frame within 0.1 deg),
    whatever weight the redundancy terms get (a `distance` term pulls by design: after 6 time constants at its
    goal, it must hold). Centering, which dominates its level at weight 1e6, still moves the joints. (The examples
    with added terms run interpreted: 32 tasks that no other test builds; the paths agree, test_generated.py.)"""
    task = vfdsl.load(_with_lines(tmp_path, task_file, redundancy) if redundancy else task_file)
    ctrl = vfdsl.compile(task, backend="interpreted" if redundancy else "auto")
    q = task.start.copy()
    if any(o.term == "distance" for o in task.objectives):
        q = _run(ctrl, task, q, 6.0, lambda k: _zero(task))[-1]
    trajectory = _run(ctrl, task, q, HANDS_OFF_SECONDS, lambda k: _zero(task))
    moved, _ = _drift(task, trajectory, _tracked_frames(task))
    _, turned = _drift(task, trajectory, {o.args["frame"].name for o in task.objectives if o.term == "track"})
    assert moved <= DRIFT_LENGTH and turned <= DRIFT_ANGLE, (moved, math.degrees(turned))
    if "centering" in redundancy:
        robot = Robot.load(task.robots[0].urdf)
        middle, half_range = (robot.lower + robot.upper) / 2, (robot.upper - robot.lower) / 2
        cost = [float(np.sum(((q - middle) / half_range) ** 2)) for q in (trajectory[0], trajectory[-1])]
        assert cost[1] <= cost[0] + 1e-9
        if "1e6" in redundancy and task.name == "lecture_remote_center":   # the arm's elbow is free
            assert cost[1] < cost[0] - 1e-4, "centering should still move the joints in the null space"


def test_the_same_centering_at_level_1_does_move_the_tip(tmp_path):
    """The hands-off check can fail: centering at the tracking level pulls the tip along."""
    task = vfdsl.load(_with_lines(tmp_path, TASKS_DIR / "lecture_remote_center.vf",
                                  "minimize centering() weight 1 priority 1"))
    ctrl = vfdsl.compile(task)
    trajectory = _run(ctrl, task, task.start.copy(), HANDS_OFF_SECONDS, lambda k: _zero(task))
    moved, _ = _drift(task, trajectory, {"tip"})
    assert moved > 10 * DRIFT_LENGTH


def _pivot_push(task, ctrl, inputs_for_speed, speed=0.01, seconds=1.0):
    """A sideways push (perpendicular to the tool and to the vertical) asking ``speed`` for ``seconds``: the
    fraction of the commanded motion the tip makes along the push, and the worst distance from the port to the
    tool axis line (Pinocchio)."""
    robot = Robot.load(task.robots[0].urdf)
    port = np.array(task.param("port").value.xyz)
    p0, R0 = robot.frame_pose(task.start, "tool_tip")
    push = np.cross(R0[:, 2], [0.0, 0.0, 1.0])
    push /= np.linalg.norm(push)
    trajectory = _run(ctrl, task, task.start.copy(), seconds, lambda k: inputs_for_speed(push * speed))
    worst = 0.0
    for q in trajectory:
        p, R = robot.frame_pose(q, "tool_tip")
        d = port - p
        worst = max(worst, float(np.linalg.norm(d - (d @ R[:, 2]) * R[:, 2])))
    p, _ = robot.frame_pose(trajectory[-1], "tool_tip")
    return float((p - p0) @ push) / (speed * seconds), worst


PORT_BOUND = 0.5e-3 / math.cos(math.pi / 8)     # within 0.5 mm by an octagon: its corner distance


def test_pivot_push_on_lecture_remote_center():
    """The shipped task (a joystick twist asking 10 mm/s sideways for 1 s): the tip follows >= 80 %."""
    task = vfdsl.load(TASKS_DIR / "lecture_remote_center.vf")
    ratio, port_error = _pivot_push(task, vfdsl.compile(task), lambda v: {"stick": np.r_[v, 0, 0, 0]})
    print(f"pivot push: {ratio:.1%} of the commanded motion, port within {port_error * 1e3:.4f} mm")
    assert ratio >= 0.8 and port_error <= PORT_BOUND + 1e-7, (ratio, port_error)


def test_a_1_N_hand_push_on_the_remote_center_task(tmp_path):
    """The same task driven by hand: `input f : force`, 1 N sideways with gain 10 mm/s/N for 1 s."""
    text = (TASKS_DIR / "lecture_remote_center.vf").read_text()
    text = text.replace("input stick : twist", "input f : force").replace(
        "track(tip, stick, gain = 1, angular_gain = 1)", "track(tip, f, gain = 10 mm/s/N)")
    text += f'\nscene "{(TASKS_DIR / "lecture_remote_center.yaml").resolve()}"\n'
    (tmp_path / "hand.vf").write_text(text)
    task = vfdsl.load(tmp_path / "hand.vf")
    ratio, port_error = _pivot_push(task, vfdsl.compile(task), lambda v: {"f": v / 0.01})
    print(f"pivot push: {ratio:.1%} of the commanded motion, port within {port_error * 1e3:.4f} mm")
    assert ratio >= 0.8 and port_error <= PORT_BOUND + 1e-7, (ratio, port_error)


def test_tracking_both_parts_on_one_level_locks_the_pivot(tmp_path):
    """Why the default ranks the parts: asked to keep the rotation still on the same level, a rad/s weighing as a
    m/s (`lever = 1 m`, the weighting before priority levels), the port makes the tip barely move (the issue
    measured 0.53 mm of 10 mm)."""
    text = (TASKS_DIR / "lecture_remote_center.vf").read_text().replace(
        "gain = 1, angular_gain = 1)", "gain = 1, angular_gain = 1, lever = 1 m)")
    text += f'\nscene "{(TASKS_DIR / "lecture_remote_center.yaml").resolve()}"\n'
    (tmp_path / "lever.vf").write_text(text)
    task = vfdsl.load(tmp_path / "lever.vf")
    ratio, _ = _pivot_push(task, vfdsl.compile(task), lambda v: {"stick": np.r_[v, 0, 0, 0]})
    print(f"lever = 1 m: {ratio:.1%} of the commanded motion")
    assert ratio < 0.2, ratio


SOFT_WALL = """task soft_wall
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
minimize track(tip, f, gain = 10 mm/s/N)
minimize damping() weight 1e-6
require tip above(plane(point = [0, 0, 270], normal = [0, 0, 1])) soft weight {weight}
"""


@pytest.mark.parametrize("weight", [0.5, 4.0])
def test_soft_penetration_is_the_documented_rate_balance_at_any_period(tmp_path, weight):
    """Pushing 1 N down (asking v = 10 mm/s) into a soft wall 0.2 mm below the tip: the tip settles
    w_t v / (w k) beyond it, at dt = 1 ms and at 10 ms alike."""
    (tmp_path / "wall.vf").write_text(SOFT_WALL.format(weight=weight))
    task = vfdsl.load(tmp_path / "wall.vf")
    ctrl = vfdsl.compile(task)
    robot = Robot.load("shr7")
    q0 = np.zeros(robot.nq)
    q0[robot.joint_names.index("insert")] = 0.02
    start_z = robot.frame_pose(q0, "tool_tip")[0][2]
    q0[robot.joint_names.index("z")] += 0.2702 - start_z           # the tip 0.2 mm above the wall
    expected = 0.01 / (weight * SOFT_RESTORE_RATE)
    for dt in (1e-3, 1e-2):
        q = _run(ctrl, task, q0.copy(), 3.0, lambda k: {"f": [0.0, 0.0, -1.0]}, dt=dt)[-1]
        penetration = 0.27 - robot.frame_pose(q, "tool_tip")[0][2]
        assert penetration == pytest.approx(expected, rel=0.02), (dt, penetration, expected)


def test_tip_speed_does_not_depend_on_the_period():
    """The same push on paper B's pivot-free sibling (lecture_follow_path) moves the tip as fast at 1 ms as at
    10 ms: track asks a rate."""
    task = vfdsl.load(TASKS_DIR / "lecture_follow_path.vf")
    ctrl = vfdsl.compile(task)
    robot = Robot.load("shr7")
    along = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    speeds = []
    for dt in (1e-3, 1e-2):
        q = _run(ctrl, task, task.start.copy(), 0.5, lambda k: {"f": 2.0 * along}, dt=dt)[-1]
        speeds.append((robot.frame_pose(q, "tool_tip")[0] - robot.frame_pose(task.start, "tool_tip")[0]) @ along / 0.5)
    assert speeds[0] == pytest.approx(2e-3, rel=1e-3) and speeds[1] == pytest.approx(2e-3, rel=1e-3)


@pytest.mark.parametrize("text,message", [
    ("require tip speed(20 mm/s) priority 2", "`priority` applies to soft constraints"),
    ("minimize damping() priority 0", "a priority must be a positive whole number"),
    ("minimize damping() priority 1.5", "a priority must be a positive whole number"),
    ("minimize damping() priority 6", "priority 6 is too low a level"),
    ("minimize damping() priority 2 mm", "a priority must be a positive whole number"),
    ("minimize track(tip, f, gain = 1 mm/s/N, linear = false, angular = false)", "tracks nothing"),
    ("minimize track(tip, f, gain = 1 mm/s/N, lever = 0 mm)", "must be in (0, 1e+06]"),
    ("minimize distance(tip, [0, 0, 300], time_constant = -1 s)", "must be > 0"),
    ("minimize centering(time_constant = 5 mm)", "time"),
    ("use joint_safety() priority 2", "`use` takes no clauses"),
])
def test_bad_objective_clauses_are_clear_errors(tmp_path, text, message):
    (tmp_path / "t.vf").write_text('task t\nunits mm, deg\nimport "' + str((TASKS_DIR / "library" / "fixtures.vf")
                                   .resolve()) + '"\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
                                   'input f : force\n' + text + "\n")
    with pytest.raises(VfError) as info:
        vfdsl.load(tmp_path / "t.vf")
    assert message in str(info.value) and info.value.pos is not None and info.value.pos.line == 7


def test_levels_of_the_examples(tmp_path):
    """What each example solves first: the levels the assembly builds (track's parts ranked, redundancy last)."""
    ctrl = vfdsl.compile(vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf"), backend="interpreted")
    # a torque drives the angular part; a last level of damping alone is solved as a level of its own
    assert ctrl.assembled.levels == [["track(tip) angular"], ["track(tip) linear"], ["damping()"]]
    ctrl = vfdsl.compile(vfdsl.load(TASKS_DIR / "lecture_steady_direction.vf"), backend="interpreted")
    assert ctrl.assembled.levels == [["distance(tip)", "direction_change(tip)"], ["damping()"]]
    task = vfdsl.load(_with_lines(tmp_path, TASKS_DIR / "lecture_remote_center.vf", "minimize centering()"))
    ctrl = vfdsl.compile(task, backend="interpreted")
    assert ctrl.assembled.levels == [["track(tip) linear"], ["track(tip) angular"], ["damping()", "centering()"]]
