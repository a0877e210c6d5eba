"""tasks/polyline_guide.vf: the shr7's tip follows a planned cut, a polyline with three corners, pushed along it
by a scripted hand (5 N toward the next corner, with a wobble of 1 N); at each corner the hand turns toward
the following one once the tip has reached the corner.

Measured with Pinocchio (``Robot.frame_pose``), not with the compiler: the distance from the true tip to the
polyline, by brute force on its segments (each segment projected with numpy).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus

TASK = TASKS_DIR / "polyline_guide.vf"
EPS = 1e-4                                        # follows within 0.1 mm, an octagon


def distance_to_polyline(points: np.ndarray, x: np.ndarray) -> float:
    best = math.inf
    for a, b in zip(points, points[1:]):
        d = (b - a) / np.linalg.norm(b - a)
        t = min(max((x - a) @ d, 0.0), np.linalg.norm(b - a))
        best = min(best, float(np.linalg.norm(x - a - t * d)))
    return best


def test_check_passes(capsys):
    assert main(["check", str(TASK)]) == 0
    assert "0 errors, 0 warnings" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("backward", [False, True], ids=["forward", "backward"])
def test_pushed_along_the_cut_past_its_corners(backward):
    """Forward from the scene's start, or backward from the last point (the tool vertical above it)."""
    task = vfdsl.load(TASK)
    ctrl = vfdsl.compile(task, backend="interpreted")
    robot = Robot.load("shr7")
    points = np.array(task.param("cut").value.points)
    q = task.start.copy()
    if backward:
        points = points[::-1]
        q[:2] = points[0][:2]                      # x, y stages: the tip over the last point
    goal, reached, distances, statuses = 1, [], [], set()
    for k in range(4000):
        p, _ = robot.frame_pose(q, "tool_tip")
        along = (points[goal] - points[goal - 1]) / np.linalg.norm(points[goal] - points[goal - 1])
        if along @ (p - points[goal]) > -2e-5:                # at the corner (or the end): turn to the next
            reached.append(goal)
            if goal == len(points) - 1:
                break
            goal += 1
        push = 5.0 * (points[goal] - p) / np.linalg.norm(points[goal] - p)
        push += np.array([math.sin(0.3 * k), math.cos(0.2 * k), 0.3 * math.sin(0.7 * k)])
        q = q + ctrl.step(q, {"f": push})
        statuses.add(ctrl.status)
        distances.append(distance_to_polyline(points, robot.frame_pose(q, "tool_tip")[0]))
    assert statuses == {StepStatus.OPTIMAL}
    assert reached == [1, 2, 3, 4], "the tip should pass every corner and reach the end"
    # the octagon's corners: eps / cos(pi/8) = 108.2 um (measured: 100.2 um forward, 82.1 um backward)
    assert max(distances) <= EPS / math.cos(math.pi / 8)


def test_simulator_scores_a_polyline_exactly():
    """``vfdsl simulate``'s follows metric (vfdsl.sim.geometry.Curve) on a polyline: the brute-force distance
    everywhere, past its ends included (there: the distance to the end point)."""
    from vfdsl.sim.geometry import Curve
    task = vfdsl.load(TASK)
    value = task.param("cut").value
    points = np.array(value.points)
    rng = np.random.default_rng(61)
    x = points[rng.integers(0, len(points), 300)] + rng.normal(scale=0.003, size=(300, 3))
    s, distance = Curve(value).closest(x)
    inside = (s > 0) & (s < np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    expected = np.array([distance_to_polyline(points, p) for p in x])
    assert inside.sum() > 200                     # the corners' neighbourhoods, and the two ends
    np.testing.assert_allclose(distance[inside], expected[inside], atol=1e-15)
    np.testing.assert_allclose(distance, expected, atol=1e-15)
    assert (~inside).sum() > 10                   # points past the two ends were scored too
