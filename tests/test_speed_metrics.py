"""Speed metrics (speed, angular_speed, joint_speed) have one sample per tick, on the ticks' time base,
like every other metric: their profiles plot against the tick times and pool the same number of samples."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import TASKS_DIR
from scipy.spatial.transform import Rotation

import vfdsl
from vfdsl.cli import main
from vfdsl.kinematics.robot import Robot
from vfdsl.sim.geometry import Scene
from vfdsl.sim.metrics import Poses, errors, metric_defs

SPEEDY = """task speedy
units mm, deg
robot arm = urdf "panda7"
frame tip = arm.link("tool_tip")
input stick : twist
param port : point
minimize track(tip, stick, gain = 1, angular_gain = 1)
minimize damping() weight 1e-4
require tip passes_through(port) within 0.5 resolution 8
require tip speed(5 mm/s)
require tip angular_speed(20 deg/s)
require joint_limits()
require joint_speed()
"""


@pytest.fixture
def speedy(tmp_path):
    (tmp_path / "speedy.vf").write_text(SPEEDY)
    (tmp_path / "speedy.yaml").write_text((TASKS_DIR / "lecture_remote_center.yaml").read_text())
    return tmp_path / "speedy.vf"


def test_speed_metrics_of_hand_computed_poses_have_one_sample_per_tick(speedy):
    """The tip moves 0.1 mm a tick (10 mm/s at 10 ms) and turns 0.3 deg a tick (30 deg/s): 5 mm/s over its
    speed limit and 10 deg/s over its angular one, at every tick but the first, which has no step before it."""
    task = vfdsl.load(speedy)
    robot = Robot.load("panda7")
    n, dt = 6, 0.01
    p = np.array([[0.3 + 1e-4 * k, 0.0, 0.5] for k in range(n)])
    R = Rotation.from_rotvec([[0.0, 0.0, math.radians(0.3) * k] for k in range(n)]).as_matrix()
    qs = np.zeros((n, robot.nq))
    qs[:, 0] = [0.01 * k for k in range(n)]                  # joint 1 at 1 rad/s
    defs = {d.name: d for d in metric_defs(task, robot, ())}
    scene, poses = Scene(task), Poses({"tip": p}, {"tip": R})
    speed = errors(defs["tip_speed_error_mm_s"], task, robot, scene, poses, qs, dt)
    turn = errors(defs["tip_angular_speed_error_deg_s"], task, robot, scene, poses, qs, dt)
    joint = errors(defs["joint_speed_deg_s"], task, robot, scene, poses, qs, dt)
    assert len(speed) == len(turn) == len(joint) == n
    np.testing.assert_allclose(speed, [0] + [5.0] * (n - 1), atol=1e-9)
    np.testing.assert_allclose(turn, [0] + [10.0] * (n - 1), atol=1e-6)
    over = math.degrees(1.0 - robot.velocity_limit[0])
    np.testing.assert_allclose(joint, [0] + [max(0.0, over)] * (n - 1), atol=1e-9)


def test_simulate_plots_a_task_with_speed_constraints(speedy, tmp_path):
    out, plot = tmp_path / "run.json", tmp_path / "run.png"
    assert main(["simulate", str(speedy), "--duration", "0.5s", "--quiet", "--json", str(out), "--plot", str(plot)]) == 0
    assert plot.stat().st_size > 1000
    doc = json.loads(out.read_text())
    samples = {name: m["samples"] for name, m in doc["metrics"].items() if "samples" in m}
    ticks = doc["ticks"]
    assert ticks == 50
    for name in ("tip_speed_error_mm_s", "tip_angular_speed_error_deg_s", "joint_speed_deg_s",
                 "tip_passes_through_error_mm"):
        assert samples[name] == ticks, (name, samples)
