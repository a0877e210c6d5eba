"""`vfdsl view`: the fixture geometry it draws, the trace it replays, and the viewer itself in a real browser.

The browser test starts `vfdsl view` in a subprocess on a free port, loads the page in headless Chromium,
reads the viewer's server-side state through its (hidden) `--control` channel on stdin, takes a
screenshot, pushes the hand (server-side), drags it with the mouse in the page, clicks the panel's Reset
button, and stops the viewer with SIGINT. It skips, saying why, only where no Chromium is installed (`.ci/run` installs Debian's `chromium`
where it is missing).
"""

from __future__ import annotations

import io
import json
import math
import os
import queue
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.errors import VfError
from vfdsl.sim.geometry import Scene
from vfdsl.sim import shapes
from vfdsl.view import replay
from vfdsl.view.browser import Browser, find_chromium
from vfdsl.view.command import STATE_PREFIX
from vfdsl.view.options import free_port

from conftest import REPO, TASKS_DIR

TASK_A = TASKS_DIR / "paper_a_follow_curve.vf"
TASK_B = TASKS_DIR / "paper_b_virtual_rcm.vf"


# ------------------------------------------------------------------------------------------------ shapes
def test_every_constraint_of_every_example_is_a_fixture_with_its_source_line():
    for path in sorted(TASKS_DIR.glob("*.vf")):
        task = vfdsl.load(path)
        if task.start is None:
            continue
        frames = vfdsl.compile(task, backend="interpreted").frames(task.start)     # no C build: fast
        fixtures = shapes.build(task, Scene(task), frames)
        assert [f.index for f in fixtures] == list(range(len(task.constraints)))
        for f, c in zip(fixtures, task.constraints):
            assert f.where.startswith(f"{c.span.file.rsplit('/', 1)[-1]}:{c.span.line}")
            if c.primitive not in shapes.NO_GEOMETRY:
                assert f.shapes, f"{path.name}: {f.title} draws nothing"
                assert all(np.isfinite(s.vertices).all() for s in f.shapes)


def test_paper_b_pivot_polytope_is_the_cube_and_its_bound_the_circumradius():
    task = vfdsl.load(TASK_B)
    frames = vfdsl.compile(task, backend="interpreted").frames(task.start)
    stays = shapes.build(task, Scene(task), frames)[0]
    by_name = {s.name: s for s in stays.shapes}
    pivot = np.array(task.param("pivot").value.xyz)
    corners = np.linalg.norm(by_name["polytope"].vertices - pivot, axis=1)
    assert len(by_name["polytope"].vertices) == 8                      # the 4x4 parametrization: a cube
    assert np.allclose(corners, math.sqrt(3) * 1e-6)                   # its corners at sqrt(3) eps
    bound = np.linalg.norm(by_name["bound"].vertices - pivot, axis=1)
    assert np.allclose(bound, math.sqrt(3) * 1e-6)
    assert "guaranteed 1.73 um" in stays.tolerance_text


def test_paper_a_curves_pass_through_their_points_in_the_plate():
    task = vfdsl.load(TASK_A)
    ctrl = vfdsl.compile(task, backend="interpreted")      # the generated C is tested elsewhere
    fixtures = shapes.build(task, Scene(task), ctrl.frames(task.start))
    tip_curve = next(s for s in fixtures[0].shapes if s.name == "curve").vertices
    shaft_curve = next(s for s in fixtures[1].shapes if s.name == "curve").vertices
    tip = ctrl.frames(task.start)["tip"].position
    assert np.min(np.linalg.norm(tip_curve.reshape(-1, 3) - tip, axis=1)) < 1e-4    # the tip starts on its curve
    shift = shaft_curve.reshape(-1, 3).mean(axis=0) - tip_curve.reshape(-1, 3).mean(axis=0)
    assert abs(np.linalg.norm(shift) - 0.1) < 1e-9                     # the copy 100 mm along the plate normal


# ------------------------------------------------------------------------------------------------ replay
def _from_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each point's distance to the segment a b."""
    t = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    return np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=1)


def test_a_mesh_fixture_draws_the_tool_s_capsule():
    """tasks/sinus_channel.vf: inside_mesh on the shaft (a capsule of radius 1 mm from the tip to 30 mm up the
    tool, 0.5 mm margin): the segment from the tip to the shaft frame, the capsule of the tool's radius around it
    and the wire capsule of radius + margin the rows keep off the wall, all drawn at the tool (moving); the
    channel as a wire frame (allowed)."""
    task = vfdsl.load(TASKS_DIR / "sinus_channel.vf")
    frames = vfdsl.compile(task, backend="interpreted").frames(task.start)
    fixture = next(f for f in shapes.build(task, Scene(task), frames) if f.title.startswith("inside_mesh(tip)"))
    by_name = {s.name: s for s in fixture.shapes}
    a, b = frames["tip"].position, frames["shaft"].position
    assert np.allclose(by_name["shaft"].vertices, [[a, b]]) and by_name["shaft"].role == "reference"
    capsule, clearance = by_name["capsule"], by_name["clearance"]
    assert capsule.role == "reference" and not capsule.wireframe
    assert clearance.role == "tolerance" and clearance.wireframe
    for shape, radius in ((capsule, 0.001), (clearance, 0.0015)):
        assert np.allclose(_from_segment(shape.vertices, a, b), radius, atol=1e-12)
        along = (shape.vertices - a) @ (b - a) / np.linalg.norm(b - a)     # its caps beyond both ends
        assert -radius <= along.min() < -0.95 * radius and 0.03 + 0.95 * radius < along.max() <= 0.03 + radius
    assert {s.name for s in fixture.shapes if s.moving} == {"shaft", "capsule", "clearance"}
    assert by_name["mesh"].role == "allowed" and by_name["mesh"].wireframe and not by_name["mesh"].moving


def test_a_point_tool_s_clearance_is_a_ball(tmp_path):
    """outside_mesh without a shaft (a point) nor a radius: no segment and no capsule, the clearance a ball of the
    margin at the tip."""
    text = (TASKS_DIR / "bone_nerve.vf").read_text()
    text = text.replace("require tip outside_mesh(nerve, margin = 2 mm, shaft = shaft, radius = 1 mm)",
                        "require tip outside_mesh(nerve, margin = 2 mm)")
    text = text.replace('import "library/fixtures.vf"', f'import "{TASKS_DIR / "library" / "fixtures.vf"}"')
    text = text.replace('"anatomy/', f'"{TASKS_DIR / "anatomy"}/')
    (tmp_path / "point.vf").write_text(text.replace("task bone_nerve", "task point"))
    (tmp_path / "point.yaml").write_text((TASKS_DIR / "bone_nerve.yaml").read_text())
    task = vfdsl.load(tmp_path / "point.vf")
    frames = vfdsl.compile(task, backend="interpreted").frames(task.start)
    fixture = next(f for f in shapes.build(task, Scene(task), frames) if f.title.startswith("outside_mesh(tip)"))
    assert [s.name for s in fixture.shapes] == ["mesh", "clearance"]
    ball = fixture.shapes[1]
    assert np.allclose(np.linalg.norm(ball.vertices - frames["tip"].position, axis=1), 0.002)


def test_the_viewer_moves_the_capsule_with_the_tool_and_keeps_the_mesh():
    """In the viewer, the channel fixture's capsule nodes follow the tool as the hand pushes it (redrawn around
    the tool's new segment); the channel's mesh node is not sent again."""
    from vfdsl.view.app import Viewer
    task = vfdsl.load(TASKS_DIR / "sinus_channel.vf")
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        base = "/fixtures/c0_inside_mesh_tip"
        assert {f"{base}/mesh", f"{base}/shaft", f"{base}/capsule", f"{base}/clearance"} <= set(viewer.state()["scene_nodes"])
        mesh, start = viewer.nodes[f"{base}/mesh"], viewer.frames["tip"].position.copy()
        viewer.push([0.0, 0.0, -0.01])
        for _ in range(30):
            viewer.tick()
        a, b = viewer.frames["tip"].position, viewer.frames["shaft"].position
        assert np.linalg.norm(a - start) > 1e-3                          # the tool moved (mm)
        capsule = np.asarray(viewer.nodes[f"{base}/capsule"].vertices, dtype=float)
        assert np.abs(_from_segment(capsule, a, b) - 0.001).max() < 1e-4     # around where the tool is now
        assert np.allclose(np.asarray(viewer.nodes[f"{base}/shaft"].points, dtype=float).reshape(-1, 3), [a, b],
                           atol=1e-4)
        assert viewer.nodes[f"{base}/mesh"] is mesh
    finally:
        viewer.close()


def test_replay_reads_the_simulate_trace_columns_and_picks_a_trial(tmp_path):
    joints = ["x", "y", "z", "rcm_a", "rcm_b", "roll", "insert"]
    header = ["trial", "seed", "tick", "t_s"] + [f"q.{j}_{'rad' if j.startswith('r') else 'm'}" for j in joints] \
        + ["status", "violations", "metric.tip_error_m", "tracker.tip_error_m"]
    rows = []
    for trial in (0, 1):
        for k in range(5):
            q = [0.001 * k, 0, 0, 0.01 * trial, 0, 0, 0.01]
            rows.append([trial, 7, k, 0.01 * k, *q, 0, "", 1e-6 * k, 2e-6 * k])
    path = tmp_path / "run.csv"
    path.write_text("\n".join(",".join(map(str, r)) for r in [header, *rows]) + "\n")
    trace = replay.read(path, joints)
    assert trace.trial == "0" and len(trace.t) == 5
    assert np.allclose(trace.q[:, 0], 0.001 * np.arange(5))
    assert trace.error_name == "metric.tip_error_m" and np.allclose(trace.error, 1e-6 * np.arange(5))
    assert np.allclose(replay.read(path, joints, trial="1").q[:, 3], 0.01)
    with pytest.raises(VfError, match="no trial"):
        replay.read(path, joints, trial="9")


def test_replay_reads_indexed_and_named_joint_columns_in_mm_and_deg(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text("time,q[0],q_b_deg,error_mm\n0,1,90,0.5\n0.1,2,180,\n")
    trace = replay.read(path, ["a", "b"])
    assert np.allclose(trace.q, [[1, math.pi / 2], [2, math.pi]])
    assert trace.error[0] == pytest.approx(5e-4) and np.isnan(trace.error[1])
    path.write_text("time,q[0]\n0,1\n")
    with pytest.raises(VfError, match=r"no column for joint 1 \(b\)"):
        replay.read(path, ["a", "b"])


def test_replay_viewer_shows_the_row_at_a_time(tmp_path):
    from vfdsl.view.app import Viewer
    task = vfdsl.load(TASK_B)
    ctrl = vfdsl.compile(task, backend="interpreted")      # the generated C is tested elsewhere
    q0 = task.start
    lines = ["t," + ",".join(f"q[{i}]" for i in range(7)) + ",tip_error"]
    for k in range(20):
        q = q0.copy()
        q[3] += 0.002 * k
        lines.append(f"{0.01 * k}," + ",".join(map(str, q)) + f",{1e-6 * k}")
    (tmp_path / "b.csv").write_text("\n".join(lines) + "\n")
    trace = replay.read(tmp_path / "b.csv", ctrl.assembled.context.robot.joint_names)
    viewer = Viewer(task, ctrl, port=free_port(), replay=trace)
    try:
        viewer.show_time(0.105)
        state = viewer.state()
        assert state["ticks"] == 10 and np.allclose(state["q"], trace.q[10])
        assert "/trace" in state["scene_nodes"] and "tip_error = 0.01 mm" in state["readout"]
    finally:
        viewer.close()


def test_replay_moves_the_params_the_trace_records(tmp_path):
    from vfdsl.compiler.context import flatten
    from vfdsl.view.app import Viewer
    task = vfdsl.load(TASKS_DIR / "breathing_vessel.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")      # the generated C is tested elsewhere
    points = np.array(task.param("vessel").value.points)
    header = ["t_s"] + [f"q.{j}" for j in ctrl.assembled.context.robot.joint_names] \
        + [f"param.vessel.p{i}.{a}_m" for i in range(len(points)) for a in "xyz"]
    rows = [[0.01 * k, *task.start, *(points + [0.0, 0.001 * k, 0.0]).ravel()] for k in range(3)]
    path = tmp_path / "vessel.csv"
    path.write_text("\n".join(",".join(map(str, r)) for r in [header, *rows]) + "\n")
    sizes = {n: len(flatten(ctrl.param_defaults[n])) for n in ctrl.param_names}
    trace = replay.read(path, ctrl.assembled.context.robot.joint_names, params=sizes)
    assert trace.params["vessel"].shape == (3, points.size)
    viewer = Viewer(task, ctrl, port=free_port(), replay=trace)
    try:
        viewer.show_time(0.02)
        knots = next(s for s in viewer.fixtures[0].shapes if s.name == "points").vertices
        assert np.allclose(knots, points + [0.0, 0.002, 0.0])
    finally:
        viewer.close()


def test_a_refused_param_is_shown_and_the_controller_keeps_running():
    from vfdsl.view.app import Viewer
    task = vfdsl.load(TASK_B)
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        assert not viewer.set_param("axis", [0.0, 0.0, 0.0])
        assert "axis" in viewer.message and "refused" in viewer.message
        assert viewer.set_param("pivot", [0.0, 0.0, 0.291])
        assert viewer.message == ""
        viewer.push([0.0, 0.01, 0.0])
        for _ in range(5):
            viewer.tick()
        assert viewer.state()["ticks"] == 5
    finally:
        viewer.close()


def test_a_violated_fixture_is_marked():
    from vfdsl.view.app import Viewer
    from vfdsl.view.scene import VIOLATED
    task = vfdsl.load(TASKS_DIR / "keep_out.vf")
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        assert viewer.state()["violated_fixtures"] == []
        tip = viewer.frames["tip"].position
        assert viewer.set_param("artery", list(tip + [0.001, 0.0, 0.0]))     # the keep-out ball now holds the tip
        viewer.tick()
        state = viewer.state()
        assert state["violated_fixtures"] == ["c1_outside_sphere_tip"]
        assert any("keep_out.vf:21" in v for v in state["violations"])
        label = viewer.nodes["/fixtures/c1_outside_sphere_tip/label"]
        assert label.text.startswith("VIOLATED outside_sphere(tip) keep_out.vf:21")
        assert tuple(viewer.nodes["/fixtures/c1_outside_sphere_tip/ball"].color) == VIOLATED
    finally:
        viewer.close()


def test_a_runtime_curve_point_dragged_moves_the_curve_the_controller_follows():
    from vfdsl.view.app import Viewer
    task = vfdsl.load(TASKS_DIR / "breathing_vessel.vf")
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        n = len(task.param("vessel").value.points)
        gizmos = [f"/params/vessel/p{i}" for i in range(n)]
        assert set(gizmos) <= set(viewer.state()["scene_nodes"])
        node = viewer.nodes[gizmos[1]]
        node.position = np.asarray(node.position) + [0.0, 0.002, 0.0]           # a user drags point 2 by 2 mm
        viewer._gizmo_moved("vessel")
        assert viewer.message == ""
        assert np.allclose(viewer.overrides["vessel"].points[1],
                           np.add(task.param("vessel").value.points[1], [0.0, 0.002, 0.0]))
        curve = next(s for s in viewer.fixtures[0].shapes if s.name == "points").vertices
        assert np.allclose(curve[1], viewer.overrides["vessel"].points[1])
        viewer.tick()
        assert viewer.state()["ticks"] == 1
    finally:
        viewer.close()


def test_hard_and_soft_fixtures_look_different(tmp_path):
    from vfdsl.view.app import Viewer
    from vfdsl.sim.shapes import COLORS
    text = (TASKS_DIR / "keep_out.vf").read_text().replace("require tip outside_sphere(artery, margin)",
                                                           "require tip outside_sphere(artery, margin) soft weight 10")
    (tmp_path / "soft.vf").write_text(text.replace('import "library/fixtures.vf"',
                                                   f'import "{TASKS_DIR / "library" / "fixtures.vf"}"'))
    (tmp_path / "soft.yaml").write_text((TASKS_DIR / "keep_out.yaml").read_text())
    task = vfdsl.load(tmp_path / "soft.vf")
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        hard, soft = viewer.nodes["/fixtures/c0_within_sphere_tip/ball"], viewer.nodes["/fixtures/c1_outside_sphere_tip/ball"]
        assert tuple(hard.color) == COLORS[False]["allowed"] and tuple(soft.color) == COLORS[True]["forbidden"]
        assert viewer.nodes["/fixtures/c1_outside_sphere_tip/label"].text.startswith("soft outside_sphere(tip)")
    finally:
        viewer.close()


def test_a_plane_tilted_by_its_gizmo_tilts_the_wall():
    from vfdsl.view.app import Viewer
    from vfdsl.view.scene import wxyz
    from vfdsl.view.robot import rotation_to_z
    task = vfdsl.load(TASKS_DIR / "lecture_forbidden_half_space.vf")
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        normal = np.array([0.2, 0.0, 1.0]) / np.hypot(0.2, 1.0)
        viewer.nodes["/params/wall"].wxyz = wxyz(rotation_to_z(normal))        # a user tilts the plane's gizmo
        viewer._gizmo_moved("wall")
        assert viewer.message == "" and np.allclose(viewer.overrides["wall"].normal, normal)
        square = next(s for s in viewer.fixtures[0].shapes if s.name == "plane").vertices
        assert np.allclose((square - square[0]) @ normal, 0.0, atol=1e-12)
        viewer.tick()
        assert viewer.state()["ticks"] == 1
    finally:
        viewer.close()


def test_a_urdf_with_visual_geometry_is_drawn_from_it(tmp_path):
    from vfdsl.kinematics.robot import ROBOTS_DIR, Robot
    from vfdsl.view.robot import RobotDrawing
    text = (ROBOTS_DIR / "shr7.urdf").read_text()
    text = text.replace('<link name="tool_tip">', '<link name="tool_tip"><visual><origin xyz="0 0 0.05"/>'
                        '<geometry><cylinder radius="0.002" length="0.1"/></geometry></visual>', 1)
    text = text.replace('<link name="stage_x">', '<link name="stage_x"><visual>'
                        '<geometry><box size="0.1 0.02 0.01"/></geometry></visual>', 1)
    (tmp_path / "shr7v.urdf").write_text(text)
    robot = Robot(tmp_path / "shr7v.urdf")
    drawing = RobotDrawing(robot)
    assert drawing.kind == "urdf" and len(drawing.parts) == 2
    q = vfdsl.load(TASK_B).start
    poses = drawing.poses(q)
    tip_p, tip_R = robot.frame_pose(q, "tool_tip")
    shaft = [p for (R, p, _), part in zip(poses, drawing.parts) if np.ptp(part.vertices[:, 2]) > 0.09]
    assert len(shaft) == 1 and np.allclose(shaft[0], tip_p + tip_R @ [0, 0, 0.05])


# -------------------------------------------------------------------------------- flags checked up front
_INTERPRETED = ("import functools, sys, vfdsl; from vfdsl.cli import main; "
                "vfdsl.compile = functools.partial(vfdsl.compile, backend='interpreted'); sys.exit(main(sys.argv[1:]))")


def _view(*args, env=None, timeout=60):
    """`vfdsl view ARGS --no-browser` in a subprocess (its controller interpreted: no C build); it must exit by
    itself within ``timeout`` s."""
    return subprocess.run([sys.executable, "-c", _INTERPRETED, "view", *args, "--no-browser"], capture_output=True,
                          text=True, cwd=REPO, timeout=timeout, env=env)


def _refused(proc, message):
    """Exit status 2 and the one-line error (and its hint) on stderr: no traceback, no server output."""
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.startswith("error: ") and len(proc.stderr.strip().splitlines()) <= 2, proc.stderr
    assert "vfdsl view:" not in proc.stdout                     # the server never said it was up


def _check(*args):
    """The flags checked in-process, by the command's own parser, without ever starting a server."""
    import argparse
    from vfdsl.view import command, options
    parser = argparse.ArgumentParser()
    command.add_parser(parser.add_subparsers())
    return options.check(parser.parse_args(["view", str(TASK_B), *args]))


@pytest.mark.parametrize("args, message", [
    (["--port", "70000"], "--port 70000: a port is a whole number from 0 to 65535"),     # hung after a traceback
    (["--port", "-1"], "--port -1: a port is a whole number from 0 to 65535"),
    (["--host", "nosuch.invalid"], "--host nosuch.invalid: not an address"),
    (["--host", "192.0.2.1"], "--host 192.0.2.1: not an address of this machine"),        # TEST-NET-1
])
def test_a_port_or_host_the_server_cannot_listen_on_is_refused_and_the_process_exits(args, message):
    _refused(_view(str(TASK_B), *args), message)


def test_a_busy_port_is_refused_not_silently_moved():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        _refused(_view(str(TASK_B), "--port", str(port)), f"--port {port}: in use at 127.0.0.1")
        with pytest.raises(VfError, match="in use"):
            free_port("127.0.0.1", port)                         # the Viewer itself checks it too
    assert free_port("127.0.0.1", port) == port
    assert 0 < free_port() <= 65535


@pytest.mark.parametrize("args, message", [
    (["--magnify", "nan"], "--magnify nan: the tolerances are drawn from 1 (to scale) to 1000"),
    (["--magnify", "0"], "--magnify 0: the tolerances are drawn from 1"),
    (["--magnify", "-5"], "--magnify -5:"),
    (["--magnify", "1e6"], "--magnify 1e+06:"),
    (["--magnify", "inf"], "--magnify inf:"),
    (["--seconds", "inf", "--screenshot", "x.png"], "--seconds inf: a time is a finite number of seconds"),
    (["--seconds", "nan", "--screenshot", "x.png"], "--seconds nan:"),
    (["--seconds", "-1", "--screenshot", "x.png"], "--seconds -1:"),
    (["--push", "1,2"], "--push 1,2: three numbers (mm)"),
    (["--push", "nan,0,0"], "--push nan,0,0: the offset's numbers must be finite"),
    (["--push", "1e999,0,0"], "must be finite"),
    (["--size", "0x3", "--screenshot", "x.png"], "--size 0x3: a picture is at least 1 pixel"),
    (["--size", "100000x3", "--screenshot", "x.png"], "too large a picture: the limit is 8,192"),
    (["--size", "100", "--screenshot", "x.png"], "--size 100: write WIDTHxHEIGHT"),
    (["--size", "5x-5", "--screenshot", "x.png"], "write WIDTHxHEIGHT"),
])
def test_a_number_no_view_can_use_is_refused(tmp_path, args, message):
    with pytest.raises(VfError) as err:
        _check(*[str(tmp_path / a) if a == "x.png" else a for a in args])
    assert message in str(err.value)


@pytest.mark.parametrize("args, message", [
    (["--seconds", "inf", "--screenshot", "x.png"], "--seconds inf:"),     # was a traceback
    (["--magnify", "nan"], "--magnify nan:"),                             # was a traceback
])
def test_a_non_finite_number_exits_without_a_traceback(args, message):
    _refused(_view(str(TASK_B), *args), message)


@pytest.mark.parametrize("args, message", [
    (["--trial", "2"], "--trial 2: a trial is picked from a --replay trace"),
    (["--size", "640x480"], "--size 640x480: the size of a --screenshot"),
    (["--seconds", "2"], "--seconds 2: the time a --screenshot runs the controller"),
    (["--push", "5,0,0", "--replay", "run.csv"], "--push 5,0,0: a replay has no hand to hold"),
])
def test_a_flag_that_would_be_ignored_is_refused(args, message):
    with pytest.raises(VfError, match=message):
        _check(*args)


def test_a_flag_that_would_be_ignored_exits_instead_of_serving():
    _refused(_view(str(TASK_B), "--seconds", "2"), "--seconds 2: the time a --screenshot")     # served forever


def test_good_flags_pass_with_their_values_in_si():
    opts = _check("--magnify", "2.5", "--push", "5,0,-1", "--port", "0")
    assert opts.magnify == 2.5 and np.allclose(opts.push, [0.005, 0, -0.001]) and 0 < opts.port <= 65535
    assert opts.size == (1280, 800) and opts.seconds is None


def _unwritable(tmp_path):
    """A path no one can create a file at: in a read-only directory (or, for root, in /sys)."""
    if os.geteuid() == 0:
        return "/sys/vfdsl-view-test.png"
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    return str(locked / "b.png")


def test_a_screenshot_that_cannot_be_written_is_refused_before_any_browser(tmp_path):
    (tmp_path / "file").write_text("")
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    cases = [(str(tmp_path / "no" / "b.png"), "no directory"), (str(tmp_path / "file" / "b.png"), "is not a directory"),
             (str(tmp_path / "dir.png"), "it is a directory"), (str(fifo), "cannot write"),     # no reader: no wait
             (_unwritable(tmp_path), "cannot write"), (str(tmp_path / "b.jpg"), "the picture is a PNG file")]
    (tmp_path / "dir.png").mkdir()
    for path, message in cases:
        with pytest.raises(VfError, match=message):
            _check("--screenshot", path)
    # in a subprocess, with a Chromium that records being started: it never is, and the command exits at once
    marker = tmp_path / "started"
    fake = tmp_path / "chromium"
    fake.write_text(f"#!/bin/sh\ntouch {marker}\nsleep 30\n")
    fake.chmod(0o755)
    start = time.monotonic()
    proc = _view(str(TASK_B), "--screenshot", cases[0][0], env=dict(os.environ, VFDSL_CHROMIUM=str(fake)))
    _refused(proc, "cannot write")
    assert not marker.exists() and time.monotonic() - start < 20


def test_a_replay_file_that_is_no_trace_is_refused(tmp_path):
    joints = ["a", "b"]
    cases = {"binary.csv": (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe", "not a text file"),
             "nul.csv": (b"t,q0,q1\n0,1\x00,2\n", "no row with a time and every joint"),
             "empty.csv": (b"", "no rows"),
             "header.csv": (b"t,q0,q1\n", "no rows"),
             "notime.csv": (b"x,q0,q1\n0,1,2\n", "no time column"),
             "run.parquet": (b"PAR1\x00", "a trace to replay is a CSV file, not Parquet"),
             "huge_field.csv": (b"t,q0,q1\n0,1," + b"2" * 200_000 + b"\n", "not a CSV file")}
    for name, (data, message) in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(VfError, match=message):
            replay.read(tmp_path / name, joints)
    os.mkfifo(tmp_path / "pipe.csv")                           # no writer: it would block forever
    for path in (tmp_path / "pipe.csv", tmp_path, "/dev/zero"):
        with pytest.raises(VfError, match="not a regular file"):
            replay.read(path, joints)
    with pytest.raises(VfError, match="trace not found"):
        replay.read(tmp_path / "missing.csv", joints)
    (tmp_path / "one.csv").write_text("t,q0,q1\n0,1,2\n")
    with pytest.raises(VfError, match="no trial column, so no trial '2'"):
        replay.read(tmp_path / "one.csv", joints, trial="2")    # was silently ignored


def test_a_binary_replay_exits_with_a_message(tmp_path):
    (tmp_path / "run.csv").write_bytes(bytes(range(256)) * 4)
    _refused(_view(str(TASK_B), "--replay", str(tmp_path / "run.csv")), "not a text file")     # was a traceback


def test_an_infinite_error_is_missing_not_the_scale_of_the_colours(tmp_path):
    (tmp_path / "run.csv").write_text("t,q0,q1,error,status\n0,1,2,inf,1e999\n0.1,1,2,0.001,0\n")
    trace = replay.read(tmp_path / "run.csv", ["a", "b"])
    assert np.isnan(trace.error[0]) and trace.error[1] == 0.001 and np.isnan(trace.status[0])


def test_a_push_without_a_hand_is_refused_not_ignored():
    _refused(_view(str(TASKS_DIR / "lecture_stay_near_goal.vf"), "--push", "5,0,0"),
             "task 'lecture_stay_near_goal' has no input, so no hand to hold")         # the viewer served, unpushed


def test_a_replay_time_after_the_trace_is_refused(tmp_path):
    task = vfdsl.load(TASK_B)
    lines = ["t," + ",".join(f"q[{i}]" for i in range(7))] + \
        [f"{0.01 * k}," + ",".join(map(str, task.start)) for k in range(11)]
    (tmp_path / "b.csv").write_text("\n".join(lines) + "\n")
    _refused(_view(str(TASK_B), "--replay", str(tmp_path / "b.csv"), "--seconds", "5"),
             "--seconds 5: the trace lasts 0.1 s")                                     # served forever


def test_a_screenshot_run_beyond_the_tick_limit_is_refused_before_the_server(tmp_path):
    fake = tmp_path / "chromium"
    fake.write_text("#!/bin/sh\nexit 1\n")
    fake.chmod(0o755)
    proc = _view(str(TASK_B), "--screenshot", str(tmp_path / "b.png"), "--seconds", "1e9",
                 env=dict(os.environ, VFDSL_CHROMIUM=str(fake)))
    _refused(proc, "control ticks per trial: the limit is 1,000,000")


def test_a_browser_that_fails_after_the_server_started_ends_the_process(tmp_path):
    """Chromium exits at once: the error is one line, the viewer's server does not keep the process alive, and
    the browser's profile folder is removed."""
    fake = tmp_path / "chromium"
    fake.write_text("#!/bin/sh\nexit 3\n")
    fake.chmod(0o755)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = _view(str(TASK_B), "--screenshot", str(tmp_path / "b.png"),
                 env=dict(os.environ, VFDSL_CHROMIUM=str(fake), TMPDIR=str(tmp)))
    _refused(proc, "Chromium exited with status 3 before it opened its DevTools port")
    assert not (tmp_path / "b.png").exists() and not list(tmp.glob("vfdsl-chromium-*"))


def test_a_browser_that_never_answers_is_stopped_with_its_whole_group(tmp_path):
    """A Chromium that starts a helper and never opens its DevTools port: a VfError after the timeout, and
    neither it nor its helper is left running, nor its profile folder."""
    from vfdsl.view import browser as browser_module
    pids = tmp_path / "pids"
    fake = tmp_path / "chromium"
    fake.write_text(f"#!/bin/sh\nsleep 60 &\necho $$ $! > {pids}\nwait\n")
    fake.chmod(0o755)
    profiles = lambda: set(Path(tempfile.gettempdir()).glob("vfdsl-chromium-*"))
    before = profiles()
    os.environ["VFDSL_CHROMIUM"] = str(fake)
    try:
        with pytest.raises(VfError, match="did not open its DevTools port within 1 s"):
            with Browser(timeout=1.0):
                pass
    finally:
        del os.environ["VFDSL_CHROMIUM"]
    assert profiles() <= before
    deadline = time.monotonic() + 3.0                           # the killed helper is gone once the kernel is done
    while any(_running(int(pid)) for pid in pids.read_text().split()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_running(int(pid)) for pid in pids.read_text().split())
    assert browser_module.find_chromium() != str(fake)


def _running(pid: int) -> bool:
    """The process exists and is not a zombie (an orphan waits to be reaped by init)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (FileNotFoundError, ProcessLookupError):
        return False


# ------------------------------------------------------------------------------------ in a real browser
class ViewerProcess:
    """`vfdsl view TASK --no-browser --control` in a subprocess; its stdout read on a thread."""

    def __init__(self, task, port: int):
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen([sys.executable, "-m", "vfdsl.cli", "view", str(task), "--port", str(port),
                                      "--no-browser", "--control"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, env=env, cwd=REPO)
        self.lines: queue.Queue[str] = queue.Queue()
        self.output = io.StringIO()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.output.write(line)
            self.lines.put(line)

    def wait_for(self, prefix: str, timeout: float = 30.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                if self.proc.poll() is not None:
                    raise AssertionError(f"viewer exited ({self.proc.returncode}): {self.proc.stderr.read()}")
                continue
            if line.startswith(prefix):
                return line
        raise AssertionError(f"no line starting {prefix!r} in {timeout} s; output:\n{self.output.getvalue()}")

    def command(self, **command) -> dict:
        self.proc.stdin.write(json.dumps(command) + "\n")
        self.proc.stdin.flush()
        return json.loads(self.wait_for(STATE_PREFIX)[len(STATE_PREFIX):])

    def connected(self, timeout: float = 30.0) -> dict:
        """The viewer's state once a page has connected to it."""
        deadline = time.monotonic() + timeout
        state = self.command(cmd="state")
        while state["clients"] < 1 and time.monotonic() < deadline:
            time.sleep(0.3)
            state = self.command(cmd="state")
        assert state["clients"] >= 1, "the page never connected to the viewer"
        return state

    def stop(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def drag_hand(browser: Browser, state: dict, width: int, height: int) -> None:
    """Press on the hand's x arrow (projected with the page's camera, OpenCV convention) and drag 80 px along it."""
    from vfdsl.view.live import HAND_SCALE
    from vfdsl.view.scene import matrix
    camera = state["camera"]
    R, eye = matrix(camera["wxyz"]), np.asarray(camera["position"])
    focal = (height / 2) / math.tan(camera["fov"] / 2)

    def pixel(p):
        c = R.T @ (np.asarray(p) - eye)
        return np.array([width / 2 + focal * c[0] / c[2], height / 2 + focal * c[1] / c[2]])

    hand = np.asarray(state["hand"])
    x_axis = matrix(state["hand_wxyz"])[:, 0]
    start = pixel(hand + 0.7 * HAND_SCALE * x_axis)
    along = start - pixel(hand)
    along /= np.linalg.norm(along)
    browser.call("Input.dispatchMouseEvent", type="mouseMoved", x=start[0], y=start[1])
    browser.call("Input.dispatchMouseEvent", type="mousePressed", x=start[0], y=start[1], button="left", clickCount=1)
    for k in range(1, 11):
        x, y = start + 8 * k * along
        browser.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y, button="left", buttons=1)
        time.sleep(0.05)
    browser.call("Input.dispatchMouseEvent", type="mouseReleased", x=x, y=y, button="left", clickCount=1)


@pytest.fixture(scope="module")
def chromium():
    path = find_chromium()
    if path is None:
        pytest.skip("no Chromium: install Debian's `chromium` (apt-get install -y chromium; .ci/run does this "
                    "where it is missing) or set VFDSL_CHROMIUM to a Chromium or Chrome binary")
    return path


def test_viewer_in_headless_chromium_shows_the_task_moves_the_tool_and_stops_on_sigint(chromium, tmp_path):
    port = free_port()
    viewer = ViewerProcess(TASK_A, port)
    try:
        url_line = viewer.wait_for("vfdsl view:", timeout=60)
        url = f"http://127.0.0.1:{port}/"
        assert url in url_line

        with Browser(960, 640, timeout=40) as browser:
            browser.open(url)
            state = viewer.connected()
            nodes = set(state["scene_nodes"])
            expected = {"/robot", "/robot/link_0", "/frames/tip", "/frames/tip/tool_axis", "/frames/shaft",
                        "/fixtures/c0_follows_tip", "/fixtures/c0_follows_tip/curve",
                        "/fixtures/c0_follows_tip/tube", "/fixtures/c0_follows_tip/label",
                        "/fixtures/c1_follows_shaft", "/fixtures/c2_joint_limits", "/fixtures/c3_joint_speed",
                        "/hand", "/params/plate"}
            assert expected <= nodes, f"missing scene nodes: {sorted(expected - nodes)}"
            time.sleep(1.5)
            png = browser.screenshot()
            assert browser.evaluate("document.body.innerText.includes('paper_a_follow_curve')")

            # Push the hand 5 mm along x (server-side, as a drag would set it): the controller steps and the
            # tip moves along its curve.
            before = viewer.command(cmd="state")
            viewer.command(cmd="push", offset=[0.005, 0.0, 0.0])
            time.sleep(2.0)
            after = viewer.command(cmd="state")
            assert after["ticks"] > before["ticks"] + 5
            moved = np.linalg.norm(np.subtract(after["tool"], before["tool"]))
            assert moved > 1e-4, f"the tool moved only {moved * 1e3:.3f} mm"
            assert "asked" in after["readout"] and after["message"] == ""

            # A real drag in the page: the mouse takes the hand's x arrow and pulls it 80 pixels along it.
            drag_hand(browser, after, 960, 640)
            deadline = time.monotonic() + 10
            dragged = viewer.command(cmd="state")
            while np.allclose(dragged["hand"], after["hand"]) and time.monotonic() < deadline:
                time.sleep(0.2)
                dragged = viewer.command(cmd="state")
            assert np.linalg.norm(np.subtract(dragged["hand"], after["hand"])) > 0.002, "the drag did not move the hand"

            # The panel's Reset button, clicked in the page, puts the tool back at the start.
            assert browser.evaluate("(() => { for (const b of document.querySelectorAll('button')) "
                                    "if (b.textContent.trim() == 'Reset') { b.click(); return true; } "
                                    "return false; })()")
            deadline = time.monotonic() + 10
            reset = viewer.command(cmd="state")
            while reset["ticks"] >= after["ticks"] and time.monotonic() < deadline:
                time.sleep(0.2)
                reset = viewer.command(cmd="state")
            assert reset["ticks"] < after["ticks"]
            assert np.linalg.norm(np.subtract(reset["tool"], before["tool"])) < 1e-5
        (tmp_path / "view.png").write_bytes(png)
        import matplotlib.image
        pixels = matplotlib.image.imread(tmp_path / "view.png")
        assert pixels.shape[:2] == (640, 960)
        assert float(pixels[..., :3].std()) > 0.02, "the screenshot is blank"
        scene_part = pixels[:, : int(0.6 * pixels.shape[1]), :3]                # left of the GUI panel
        assert float(scene_part.std()) > 0.02, "nothing drawn in the 3-D view"

        viewer.proc.send_signal(signal.SIGINT)
        started = time.monotonic()
        code = viewer.proc.wait(timeout=10)
        assert code in (0, 130), viewer.proc.stderr.read()
        assert time.monotonic() - started < 5
    finally:
        viewer.stop()


def test_viewer_in_headless_chromium_draws_the_channel_and_the_shaft_s_capsule(chromium, tmp_path):
    """tasks/sinus_channel.vf in a real page: the channel, the shaft's segment, its capsule and its clearance are
    scene nodes the page draws (a picture that is not blank), and still are after the hand has moved the tool."""
    port = free_port()
    viewer = ViewerProcess(TASKS_DIR / "sinus_channel.vf", port)
    base = "/fixtures/c0_inside_mesh_tip"
    expected = {f"{base}/mesh", f"{base}/shaft", f"{base}/capsule", f"{base}/clearance", f"{base}/label"}
    try:
        viewer.wait_for("vfdsl view:", timeout=60)
        with Browser(960, 640, timeout=40) as browser:
            browser.open(f"http://127.0.0.1:{port}/")
            state = viewer.connected()
            assert expected <= set(state["scene_nodes"]), sorted(expected - set(state["scene_nodes"]))
            viewer.command(cmd="push", offset=[0.0, 0.0, -0.01])
            time.sleep(2.0)
            after = viewer.command(cmd="state")
            assert np.linalg.norm(np.subtract(after["tool"], state["tool"])) > 1e-3
            assert expected <= set(after["scene_nodes"]) and after["message"] == ""
            (tmp_path / "view.png").write_bytes(browser.screenshot())
        import matplotlib.image
        pixels = matplotlib.image.imread(tmp_path / "view.png")
        assert float(pixels[:, : int(0.6 * pixels.shape[1]), :3].std()) > 0.02, "nothing drawn in the 3-D view"
    finally:
        viewer.stop()


def test_a_teleoperated_task_shows_the_master_s_ghost_and_the_haptic_arrow():
    """The hand's controls are the master: dragged 30 mm down (after engage), the ghost sits at the scaled command
    (15 mm down, past the bone), the tool stops at the bone's margin, and the arrow points out of the bone with
    FORCE_LENGTH per newton of the haptic force."""
    from vfdsl.view.app import Viewer
    from vfdsl.view.teleop import FORCE_LENGTH
    task = vfdsl.load(TASKS_DIR / "teleop" / "teleop_keep_out.vf")
    viewer = Viewer(task, vfdsl.compile(task, backend="interpreted"), port=free_port())
    try:
        start = viewer.frames["tip"].position.copy()
        for _ in range(5):
            viewer.tick()                                 # engaged: the master's anchor is where the controls start
        viewer.push([0.004, 0.0, -0.03])
        for _ in range(400):
            viewer.tick()
        out = viewer.ctrl.teleop
        assert np.allclose(out.goal, start + 0.5 * np.array([0.004, 0.0, -0.03]), atol=2e-6)
        assert np.allclose(viewer.nodes["/teleop/ghost"].position, out.goal)
        tip = viewer.frames["tip"].position
        segment = np.asarray(viewer.nodes["/teleop/force"].points, dtype=float).reshape(2, 3)
        assert np.allclose(segment, [tip, tip + FORCE_LENGTH * out.force], atol=1e-6)
        assert out.force[2] > 0.5                          # pushed back up, out of the bone
        assert "haptic" in viewer.state()["readout"] and "outside_mesh" in viewer.state()["readout"]
    finally:
        viewer.close()
