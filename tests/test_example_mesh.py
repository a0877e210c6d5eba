"""Closed loop on the mesh examples, pushed against the walls: the clearance, measured by brute force over every
triangle with Pinocchio's kinematics, never falls below the margin less the documented one-tick bound
(:mod:`vfdsl.compiler.mesh_rows`: 0.48 |dx| + |dx|^2 / (2 rho)); the tip reaches its target."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.check.kinematics import frame_pose
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.load import read_mesh

TASKS = Path(__file__).resolve().parent.parent / "tasks"
ANATOMY = TASKS / "anatomy"


def _run(name: str, force, ticks: int):
    """(task, robot, joint trajectory) of ``ticks`` steps of the native controller with the hand ``force(p_tip)``."""
    task = vfdsl.load(TASKS / f"{name}.vf")
    robot = Robot.load(task.robots[0].urdf)
    ctrl = vfdsl.compile(task)
    q, qs = task.start.copy(), [task.start.copy()]
    for _ in range(ticks):
        q = q + ctrl.step(q, {"f": force(ctrl.frames(q)["tip"].position)})
        qs.append(q.copy())
    return task, robot, np.array(qs)


def _toward(target, newtons=10.0):
    def force(p):
        e = np.asarray(target) - p
        return newtons * e / max(np.linalg.norm(e), 2e-3)
    return force


def _clearances(task, robot, qs, start: str, end: str, radius: float, mesh, keep_in: bool, stride: int = 1):
    """Signed clearance of the capsule from frame ``start`` to ``end`` at every ``stride``-th sample, and the
    largest motion of its ends in one tick."""
    a = np.array([frame_pose(robot, task.frame(start), q)[0] for q in qs])
    b = np.array([frame_pose(robot, task.frame(end), q)[0] for q in qs])
    step = max(np.linalg.norm(np.diff(a, axis=0), axis=1).max(), np.linalg.norm(np.diff(b, axis=0), axis=1).max())
    clear = [brute.signed_clearance(a[i], b[i], radius, mesh.vertices, mesh.triangles, keep_in)
             for i in range(0, len(qs), stride)]
    return np.array(clear), step


def _bound(step: float, rho: float) -> float:
    return 0.48 * step + step ** 2 / (2 * rho)


@pytest.fixture(scope="module")
def channel():
    return read_mesh(ANATOMY / "channel.stl", 1e-3)


@pytest.mark.parametrize("push", [[20, 0, -2], [0, -20, 0]], ids=["bend", "side"])
def test_channel_holds_the_shaft_pushed_into_the_wall(channel, push):
    task, robot, qs = _run("sinus_channel", lambda p: np.array(push, float), 250)
    clear, step = _clearances(task, robot, qs, "tip", "shaft", 0.001, channel, keep_in=True, stride=2)
    assert clear.min() >= 0.0005 - _bound(step, 0.005) - 1e-9, (clear.min(), step)
    assert clear.min() < 0.0006            # it did reach the wall's margin: the push was resisted


def test_channel_tip_reaches_the_target(channel):
    target = np.array([0.0096, 0.0, 0.236])
    task, robot, qs = _run("sinus_channel", _toward(target), 700)
    clear, step = _clearances(task, robot, qs, "tip", "shaft", 0.001, channel, keep_in=True, stride=5)
    assert np.linalg.norm(frame_pose(robot, task.frame("tip"), qs[-1])[0] - target) < 2e-4
    assert clear.min() >= 0.0005 - _bound(step, 0.005) - 1e-9


def test_nerve_keeps_the_tool_away_and_the_tip_reaches_the_bone():
    nerve = read_mesh(ANATOMY / "nerve.stl", 1e-3)
    bone = read_mesh(ANATOMY / "bone.stl", 1e-3)
    toward_nerve = _toward([0.006, 0.0, 0.259], 20.0)
    task, robot, qs = _run("bone_nerve", toward_nerve, 300)
    clear, step = _clearances(task, robot, qs, "tip", "shaft", 0.001, nerve, keep_in=False, stride=2)
    assert clear.min() >= 0.002 - _bound(step, 0.0015) - 1e-9
    assert clear.min() < 0.0021            # pushed onto the nerve's margin
    shaft, step = _clearances(task, robot, qs, "neck", "shaft", 0.001, bone, keep_in=False, stride=2)
    assert shaft.min() >= 0.001 - _bound(step, 0.008) - 1e-9
    target = np.array([-0.008, 0.0, 0.2573])
    task, robot, qs = _run("bone_nerve", _toward(target), 500)
    assert np.linalg.norm(frame_pose(robot, task.frame("tip"), qs[-1])[0] - target) < 2e-4
