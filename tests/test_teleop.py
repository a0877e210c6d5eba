"""Teleoperation (the `teleop` term and its haptic readout, vfdsl/objectives/teleop.py, haptics.py): a master's pose
moves the slave as it moves since engage, scaled; the clutch holds the slave and re-anchors; the force fed back is
what the fixtures stopped of the master's command, k x its depth past them along their normals.

Each figure is computed here from the controller's own readout and kinematics, on both paths."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.errors import VfError

WALL = """task teleop_wall
units mm, deg
robot psm = urdf "psm6"
frame tip = psm.link("tool_tip")
input master : pose
input clutch : button
param floor : plane = plane(point = [0, 0, -120], normal = [0, 0, 1])
param camera : pose = pose(translation = [0, 0, 0], rpy = [0, 0, 30])
monitor pressed = clutch
monitor released = not clutch
minimize damping() weight 1e-6
require tip above(floor)
phase following initial {
    capture s0 = tip.pose
    capture m0 = master
    minimize teleop(tip, master, anchor = s0, master_anchor = m0, scale = 0.5, camera = camera,
                    stiffness = 0.2 N/mm, damping = 1 N*s/m, saturation = 3 N, rate_limit = 200 N/s, ramp = 100 ms)
}
phase clutched {
}
transition following -> clutched when pressed
transition clutched -> following when released
"""
START = "start: [0, 0, 100 mm, 0, 0, 0]\nperiod: 1 ms\n"          # tip at (0, 0, -103.7) mm: 16.3 mm above the floor
SCALE, STIFFNESS, SATURATION, TAU = 0.5, 200.0, 3.0, 0.01
CAMERA = np.array([[np.cos(np.pi / 6), -np.sin(np.pi / 6), 0], [np.sin(np.pi / 6), np.cos(np.pi / 6), 0], [0, 0, 1]])


@pytest.fixture(scope="module", params=["interpreted", "native"])
def wall(request, tmp_path_factory):
    folder = tmp_path_factory.mktemp("teleop")
    (folder / "wall.vf").write_text(WALL)
    (folder / "wall.yaml").write_text(START)
    task = vfdsl.load(folder / "wall.vf")
    return task, vfdsl.compile(task, backend=request.param)


def drive(ctrl, task, masters, clutch=None):
    """Runs the master poses (ticks x 6) through a fresh start; returns per tick the readout and the tip."""
    ctrl.reset()
    q = np.array(task.start, dtype=float)
    out = []
    for k, m in enumerate(masters):
        dq = ctrl.step(q, {"master": m, "clutch": [0.0 if clutch is None else clutch[k]]})
        q = q + dq
        out.append((ctrl.teleop, ctrl.frames(q)["tip"].position, ctrl.phase))
    return out


def master_path(*legs, ticks_per_leg=500, hold=300):
    """Master positions moving linearly through the given points (m), each leg in ticks_per_leg ticks, then held."""
    points = [np.zeros(3), *map(np.asarray, legs)]
    rows = [a + (b - a) * (k + 1) / ticks_per_leg for a, b in zip(points, points[1:]) for k in range(ticks_per_leg)]
    rows += [points[-1]] * hold
    return np.hstack([np.array(rows), np.zeros((len(rows), 3))])


def test_free_motion_feels_nothing(wall):
    """Above the floor, moving 20 mm/s in every direction (tracking lags v tau behind): no force at all."""
    task, ctrl = wall
    run = drive(ctrl, task, master_path([0.01, 0.01, -0.01], [-0.01, 0.005, 0.0], [0.0, 0.0, 0.01]))
    forces = np.array([r.force for r, _, _ in run])
    assert np.abs(forces).max() < 0.05
    assert not any(r.acting for r, _, _ in run)
    lag = max(np.linalg.norm(r.goal - tip) for r, tip, _ in run)
    assert lag > 1e-5                      # the slave lagged behind its goal: the force ignores the lag


@pytest.mark.parametrize("backend", ["interpreted", "native"])
def test_a_teleop_task_without_a_constraint_row_compiles_and_feels_nothing(tmp_path, backend):
    """Only joint bounds (no fixture row): the readout's depth and force are structural zeros; they compiled to a
    sparse output and every command (check, compile, simulate, export) stopped with a Python traceback."""
    free = WALL.replace("param floor : plane = plane(point = [0, 0, -120], normal = [0, 0, 1])\n", "")
    free = free.replace("require tip above(floor)", "require joint_limits()")
    (tmp_path / "free.vf").write_text(free)
    (tmp_path / "free.yaml").write_text(START)
    task = vfdsl.load(tmp_path / "free.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    run = drive(ctrl, task, master_path([0.01, 0.0, -0.05], ticks_per_leg=200, hold=50))
    assert np.abs(np.array([r.force for r, _, _ in run])).max() == 0.0
    assert np.array([r.depth for r, _, _ in run]).shape == (250, 3)
    assert not any(len(r.acting) for r, _, _ in run)
    assert np.linalg.norm(run[-1][0].goal - run[-1][1]) < 1e-3      # followed the scaled master, unhindered


@pytest.mark.parametrize("depth", [0.005, 0.010])
def test_a_wall_feels_k_times_the_masters_depth_along_its_normal(wall, depth):
    """The master pushed `depth` past where the scaled command meets the floor: F = k depth along the floor's normal
    (in the master's base frame: through the camera), within 5 %, until the saturation."""
    task, ctrl = wall
    reach = 0.0163 / SCALE                                  # master motion that brings the slave to the floor
    down = CAMERA.T @ np.array([0.0, 0.0, -(reach + depth)])  # the world's -z, in the master's base frame
    run = drive(ctrl, task, master_path(down, ticks_per_leg=800, hold=700))
    out, tip, _ = run[-1]
    force = out.force
    expected = min(STIFFNESS * depth, SATURATION)
    normal = CAMERA.T @ np.array([0.0, 0.0, 1.0])           # the wall pushes the master back up
    assert abs(force @ normal - expected) <= 0.05 * expected
    # k x the master's depth past the floor (the engage tick took the master 1/800 of the way already), to the
    # projection's regularization (haptics.EPS = 1e-6: a factor 1 / (1 + EPS) along one normal)
    exact = (tip[2] - out.goal[2]) / SCALE
    assert force @ normal == pytest.approx(min(STIFFNESS * exact, SATURATION), rel=2e-6)
    assert np.linalg.norm(force - (force @ normal) * normal) <= 1e-3 * expected
    assert run[-1][0].acting == (f"above(tip) [{task.span.file}:12]",) or run[-1][0].acting[0].startswith("above(tip)")
    assert run[-1][1][2] == pytest.approx(-0.120, abs=1e-6)   # the slave on the floor


def test_a_wall_pushes_the_master_out_and_never_pulls_it_in(wall):
    """Withdrawing from the floor at 20 mm/s, the damping's -b d(depth)/dt pointed into the floor: the master was
    pulled in while still past it (down to -0.01 N) and at the tick contact ended. Now the force is never along the
    depth, and once no row acts it only decays to 0 (the rate limit)."""
    task, ctrl = wall
    reach = 0.0163 / SCALE
    down = list(np.linspace(0.0, -(reach + 0.0005), 700)) + [-(reach + 0.0005)] * 300
    up = [-(reach + 0.0005) + 0.00002 * k for k in range(1, 200)]
    masters = np.zeros((len(down) + len(up), 6))
    masters[:, 2] = down + up
    out = drive(ctrl, task, masters)
    force = np.array([t.force for t, _, _ in out])
    assert force[999, 2] == pytest.approx(STIFFNESS * 0.0005, rel=1e-3)     # pressed 0.5 mm past: 0.1 N up
    assert np.all(force[:, 2] >= -1e-12)                                     # never down, into the floor
    released = next(k for k in range(1000, len(out)) if not out[k][0].acting)
    assert np.all(np.diff(force[released - 1:released + 5, 2]) <= 1e-15)    # decays once nothing acts


def test_sliding_along_the_wall_feels_only_the_depth(wall):
    """Pressed 5 mm into the floor and moved along it: the force stays k x 5 mm, normal, while the slave slides."""
    task, ctrl = wall
    reach = 0.0163 / SCALE + 0.005
    down = CAMERA.T @ np.array([0.0, 0.0, -reach])
    along = down + CAMERA.T @ np.array([0.02, 0.01, 0.0])
    run = drive(ctrl, task, master_path(down, along, ticks_per_leg=800, hold=300))
    sliding = [r.force for r, _, _ in run[1000:1600]]
    normal = CAMERA.T @ np.array([0.0, 0.0, 1.0])
    assert all(abs(f @ normal - STIFFNESS * 0.005) <= 0.05 * STIFFNESS * 0.005 for f in sliding)
    assert max(np.linalg.norm(f - (f @ normal) * normal) for f in sliding) <= 0.02 * STIFFNESS * 0.005


def test_clutch_holds_the_slave_and_reengages_without_a_step(wall):
    """Move, clutch and bring the master back, release, move again: the slave moves only while following, and no
    tick moves its set-point more than the scaled master moved that tick (no step at either edge)."""
    task, ctrl = wall
    a = master_path([0.01, 0.0, -0.005], [0.0, 0.0, 0.0], [0.01, 0.0, -0.005], ticks_per_leg=400, hold=200)
    clutch = np.zeros(len(a))
    clutch[400:800] = 1.0                                   # clutched while the master goes back to its start
    run = drive(ctrl, task, a, clutch)
    phases = [phase for _, _, phase in run]
    assert phases[399] == "following" and set(phases[400:800]) == {"clutched"} and phases[800] == "following"
    tips = np.array([tip for _, tip, _ in run])
    assert np.abs(np.diff(tips[400:800], axis=0)).max() < 1e-9        # held while clutched
    setpoints = np.array([r.setpoint[:3] for r, _, _ in run])
    step = np.linalg.norm(np.diff(setpoints, axis=0), axis=1)
    master_step = SCALE * np.linalg.norm(np.diff(a[:, :3], axis=0), axis=1).max()
    assert step.max() <= master_step * (1 + 1e-9)
    assert not run[500][0].following and run[900][0].following
    # re-anchored at engage (tick 800): the slave where it was held, the master where it was then
    assert np.allclose(tips[-1], tips[799] + SCALE * CAMERA @ (a[-1, :3] - a[800, :3]), atol=1e-9)


def test_tracking_error_in_free_motion_is_speed_times_tau(wall):
    """docs/language.md: where no fixture acts, the slave trails its goal by v tau (v its speed) once the motion is
    steady, the discrete lag of dp = (g - p) dt / tau: v (tau - dt) after the tick's motion."""
    task, ctrl = wall
    run = drive(ctrl, task, master_path([0.02, 0.0, 0.0], ticks_per_leg=1000, hold=0))
    speed = SCALE * 0.02 / 1.0                               # m/s
    lag = np.linalg.norm(run[900][0].goal - run[900][1])
    assert lag == pytest.approx(speed * (TAU - 0.001), rel=0.01)         # after this tick's dq: v (tau - dt)


def test_the_force_ramps_in_after_engage(wall):
    """Engaged while the master already points past the floor: the force grows over the 100 ms ramp (and the rate
    limit), not at once."""
    task, ctrl = wall
    reach = 0.0163 / SCALE + 0.005
    a = master_path(CAMERA.T @ np.array([0.0, 0.0, -reach]), ticks_per_leg=800, hold=400)
    clutch = np.zeros(len(a))
    clutch[900:1000] = 1.0
    run = drive(ctrl, task, a, clutch)
    forces = np.array([np.linalg.norm(r.force) for r, _, _ in run])
    assert forces[999] < 1e-9                                # clutched: nothing
    assert np.abs(np.diff(forces)).max() <= 200.0 * 0.001 + 1e-12
    # re-engaged with new anchors: the floor no longer stops the (new) command, so the force stays 0
    assert forces[-1] < 1e-9


def test_a_teleop_term_needs_a_pose_master(tmp_path):
    (tmp_path / "t.vf").write_text(WALL.replace("input master : pose", "input master : force")
                                   .replace("master_anchor = m0", "master_anchor = camera"))
    (tmp_path / "t.yaml").write_text(START)
    with pytest.raises(VfError, match="teleop follows a master's pose; 'master' is a force") as info:
        vfdsl.load(tmp_path / "t.vf")
    assert "a force is read by track" in str(info.value)
    (tmp_path / "t.vf").write_text(WALL.replace("teleop(tip, master,", "teleop(tip, clutch,"))
    with pytest.raises(VfError, match="'clutch' is a button") as info:   # the hint said "read by track"
        vfdsl.load(tmp_path / "t.vf")
    assert "a button is read by monitors" in str(info.value)


@pytest.mark.parametrize("written, message", [("rotation = sideways, stiffness = 1 N/mm", "one of relative, absolute"),
                                              ("stiffness = 2 N", "expected a stiffness"),
                                              ("stiffness = -1 N/mm", "stiffness")])
def test_bad_teleop_arguments_are_refused_at_their_place(tmp_path, written, message):
    (tmp_path / "t.vf").write_text(WALL.replace("stiffness = 0.2 N/mm", written))
    (tmp_path / "t.yaml").write_text(START)
    with pytest.raises(VfError, match=message) as info:
        vfdsl.load(tmp_path / "t.vf")
    assert info.value.pos is not None and info.value.pos.line == 17


@pytest.mark.parametrize("written, message", [("scale = 500,", "'scale' must be in \\(0, 100\\], got 500"),
                                              ("scale = 0,", "'scale' must be in \\(0, 100\\], got 0"),
                                              ("scale = 100.5,", "must be in \\(0, 100\\]")])
def test_a_scale_written_upside_down_is_refused_at_its_place(tmp_path, written, message):
    """A ratio of 1:500 written as 500 would move the tool half a metre per millimetre of the hand: refused at the
    value, with the hint saying which way the ratio goes; 100 (the limit) and 0.002 load."""
    (tmp_path / "t.yaml").write_text(START)
    (tmp_path / "t.vf").write_text(WALL.replace("scale = 0.5,", written))
    with pytest.raises(VfError, match=message) as info:
        vfdsl.load(tmp_path / "t.vf")
    assert info.value.pos is not None and info.value.pos.line == 16
    assert "0.2 moves the tool 1 mm per 5 mm of the hand" in str(info.value)
    for allowed in ("scale = 100,", "scale = 0.002,"):
        (tmp_path / "t.vf").write_text(WALL.replace("scale = 0.5,", allowed))
        vfdsl.load(tmp_path / "t.vf")


def test_a_haptic_force_beyond_any_master_is_refused(tmp_path):
    (tmp_path / "t.yaml").write_text(START)
    (tmp_path / "t.vf").write_text(WALL.replace("saturation = 3 N", "saturation = 3000 N"))
    with pytest.raises(VfError, match="'saturation' must be in \\(0, 1000\\]") as info:
        vfdsl.load(tmp_path / "t.vf")
    assert info.value.pos is not None and info.value.pos.line == 17


@pytest.mark.parametrize("backend", ["interpreted", "native"])
def test_a_scale_held_in_a_param_is_held_to_the_same_limit(tmp_path, backend):
    """scale = gain, a run-time param: 500 in the scene is refused at the scene's line (naming where it is used);
    500 given to step() is refused before anything moves, on both paths, and the next tick with 0.25 runs."""
    text = (WALL.replace("param camera", "param gain : number = 0.5\nparam camera")
            .replace("scale = 0.5,", "scale = gain,"))
    (tmp_path / "t.vf").write_text(text)
    (tmp_path / "t.yaml").write_text(START + "params:\n  gain: 500\n")
    with pytest.raises(VfError, match="'scale', which must be in \\(0, 100\\]; its value is 500") as info:
        vfdsl.load(tmp_path / "t.vf")
    assert info.value.pos is not None and info.value.pos.line == 4
    (tmp_path / "t.yaml").write_text(START)
    task = vfdsl.load(tmp_path / "t.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    q, u = np.array(task.start, dtype=float), {"master": np.zeros(6), "clutch": [0.0]}
    with pytest.raises(VfError, match="param 'gain' = 500 \\(SI\\) must be in \\(0, 100\\]"):
        ctrl.step(q, u, params={"gain": 500.0})
    assert np.all(np.isfinite(ctrl.step(q, u, params={"gain": 0.25})))


TELEOP_TASKS = Path(__file__).resolve().parent.parent / "tasks" / "teleop"


@pytest.mark.parametrize("name", ["teleop_keep_out", "teleop_guide_line"])
def test_the_examples_simulate_with_an_operator(tmp_path, name):
    """Each example's scene: the master is followed 5 s of 6 (1 s clutched), fixtures act, free motion feels under
    0.05 N, and the slave holds while clutched (by the trace)."""
    from vfdsl.cli import main
    out, trace = tmp_path / "run.json", tmp_path / "run.csv"
    assert main(["simulate", str(TELEOP_TASKS / f"{name}.vf"), "--json", str(out), "--trace", str(trace),
                 "--plot", str(tmp_path / "run.png"), "--quiet"]) == 0
    assert (tmp_path / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    row = json.loads(out.read_text())["teleop"][0]
    assert row["following_s"] == pytest.approx(5.0, abs=2e-3)
    assert row["acting_s"] > 0.5
    assert row["force_free_max_N"] < 0.05
    assert 0.5 < row["force_acting_max_N"] <= 4.0 + 1e-9
    assert row["command_error_max_m"] < 2e-4
    import csv
    rows = list(csv.DictReader(trace.open()))
    clutched = [r for r in rows if r["following"] == "0"]
    joints = [k for k in rows[0] if k.startswith("dq_")]
    assert len(clutched) == 1000 and all(abs(float(r[j])) < 1e-12 for r in clutched[1:] for j in joints)
    assert all(float(r["haptic_x_N"]) ** 2 + float(r["haptic_z_N"]) ** 2 < 1e-18 for r in clutched[100:])


def test_a_scene_without_an_operator_says_the_master_rests(tmp_path, capsys):
    from vfdsl.cli import main
    scene = tmp_path / "s.sim.yaml"
    scene.write_text("units: mm, deg\nduration: 0.05 s\n")
    assert main(["simulate", str(TELEOP_TASKS / "teleop_guide_line.vf"), "--scene", str(scene)]) == 0
    out = capsys.readouterr().out
    assert "no operator (the scene has no operator:): the master rests where it starts" in out
    assert "followed (s)" in out


@pytest.mark.parametrize("operator, message", [
    ("{input: clutch, path: [{at: 0 s, position: [0, 0, 0]}]}", "the operator moves a master's pose; 'clutch' is a "
                                                                "button"),
    ("{input: master, path: [{at: 1 s, position: [0, 0, 0]}, {at: 0.5 s, position: [0, 0, 1]}]}", "must increase"),
    ("{input: master, path: [{at: 0 s, position: [0, 0, 5000]}]}", "beyond"),
    ("{input: master}", "needs 'path'"),
])
def test_a_bad_operator_is_refused_at_its_line(tmp_path, capsys, operator, message):
    from vfdsl.cli import main
    scene = tmp_path / "s.sim.yaml"
    scene.write_text(f"units: mm, deg\nduration: 0.1 s\noperator: {operator}\n")
    assert main(["simulate", str(TELEOP_TASKS / "teleop_guide_line.vf"), "--scene", str(scene)]) == 2
    err = capsys.readouterr().err
    assert message in err and "s.sim.yaml:3" in err and "Traceback" not in err


@pytest.mark.parametrize("master_damping, severity", [(None, "note"), ("0.5 N*s/m", "warning"), ("2 N*s/m", None)])
def test_check_states_the_passivity_bound(tmp_path, master_damping, severity):
    """VF970: K T / 2 + B = 200 N/m x 1 ms / 2 + 1 N s/m = 1.1 N s/m of master damping needed."""
    extra = "" if master_damping is None else f", master_damping = {master_damping}"
    (tmp_path / "t.vf").write_text(WALL.replace("ramp = 100 ms)", f"ramp = 100 ms{extra})"))
    (tmp_path / "t.yaml").write_text(START)
    report = vfdsl.check(vfdsl.load(tmp_path / "t.vf"), samples=0, backend="interpreted")
    found = [f for f in report.findings if f.code == "VF970"]
    if severity is None:
        assert not found
        return
    assert {f.severity.value for f in found} == {severity} and found[0].span.line == 16
    assert found[0].data["needed"] == pytest.approx(200.0 * 0.001 / 2 + 1.0)


def test_check_finds_where_the_scaled_master_outreaches_the_fixture(tmp_path):
    """VF971: the master reaches 40 mm, scaled 0.5: 20 mm down from the start, but the floor is 16.3 mm below: the
    tool stops 3.7 mm short, straight down, and the master feels 0.2 N/mm x 3.7 mm / 0.5."""
    (tmp_path / "t.vf").write_text(WALL.replace("ramp = 100 ms)", "ramp = 100 ms, master_reach = 40 mm)"))
    (tmp_path / "t.yaml").write_text(START)
    report = vfdsl.check(vfdsl.load(tmp_path / "t.vf"), samples=0)     # generated: the check runs 2 s per direction
    found = [f for f in report.findings if f.code == "VF971"]
    assert len(found) == 1 and found[0].severity.value == "warning"
    assert found[0].data["shortfall"] == pytest.approx(0.0037, abs=2e-5)
    assert np.allclose(found[0].data["direction"], [0, 0, -1])
    assert found[0].data["force"] == pytest.approx(min(STIFFNESS * 0.0037 / SCALE, SATURATION), rel=0.02)


@pytest.mark.parametrize("name", ["teleop_keep_out", "teleop_guide_line"])
def test_the_examples_are_sound_and_explain_their_warnings(name):
    path = TELEOP_TASKS / f"{name}.vf"
    report = vfdsl.check(vfdsl.load(path), samples=20)      # generated: the workspace check runs 2 s per direction
    assert report.exit_status() == 0, report.render_text()
    for finding in report.findings:
        if finding.severity.value == "warning":
            assert finding.code in path.read_text(), f"{name} does not say why {finding.code} stands"


ROTATING = WALL.replace("param camera : pose = pose(translation = [0, 0, 0], rpy = [0, 0, 30])",
                        "param camera : pose = pose(translation = [0, 0, 0], rpy = [0, 0, 30])\n"
                        "param gain : number = 0.5")


def _rotated(rotation: str, tmp_path):
    text = ROTATING.replace("scale = 0.5, camera = camera,", f"scale = k, camera = camera, rotation = {rotation},")
    text = text.replace("    capture m0 = master\n", "    capture m0 = master\n    capture k = gain\n")
    (tmp_path / "r.vf").write_text(text)
    (tmp_path / "r.yaml").write_text(START)
    task = vfdsl.load(tmp_path / "r.vf")
    return task, vfdsl.compile(task, backend="interpreted")


def _turned(ctrl, task, rpy, ticks=400, ramp=200):
    """The master turned to rpy, ramped in over ``ramp`` ticks (0: at once), held until ``ticks``."""
    q = np.array(task.start, dtype=float)
    master = np.zeros(6)
    for k in range(ticks):
        master[3:] = np.asarray(rpy) * (min(1.0, k / ramp) if ramp else 1.0)
        q = q + ctrl.step(q, {"master": master, "clutch": [0.0]})
    return q, ctrl.frames(q)["tip"]


def _rot(rpy):
    from vfdsl.compiler.geometry import rotation
    return rotation(rpy)


@pytest.mark.parametrize("rotation", ["relative", "absolute", "locked"])
def test_each_rotation_mode_turns_the_tool_as_documented(tmp_path, rotation):
    """The master turned by rpy (0.1, -0.05, 0.2) rad since engage: relative gives R_c R_m R_m0' R_c' R_s0 (R_m0 = I),
    absolute R_c R_m (the master held, from the first tick, at an orientation that puts the tool 0.2 rad from its
    start), locked R_s0, each reached to 1e-6."""
    from vfdsl.compiler.geometry import rpy_of
    task, ctrl = _rotated(rotation, tmp_path)
    start = ctrl.frames(np.array(task.start))["tip"].rotation
    rpy = np.array([0.1, -0.05, 0.2])
    if rotation == "absolute":
        rpy = np.array(rpy_of(CAMERA.T @ start @ _rot([0.1, -0.05, 0.2])))
    _, tip = _turned(ctrl, task, rpy, ticks=1000 if rotation == "absolute" else 400,
                     ramp=0 if rotation == "absolute" else 200)
    R_m = _rot(rpy)
    expected = {"relative": CAMERA @ R_m @ CAMERA.T @ start, "absolute": CAMERA @ R_m, "locked": start}[rotation]
    assert np.linalg.norm(tip.rotation - expected) < 1e-6


@pytest.mark.parametrize("backend", ["interpreted", "native"])
def test_a_master_turned_half_a_turn_turns_the_tool_half_a_turn(tmp_path, backend):
    """The master turned by yaw = pi since engage asks the tool half a turn about world z (R_c Rz(pi) R_c' = Rz(pi)): the
    error R_g R' is then a rotation by 180 deg - 1.2e-16 (sin(pi) in rpy_matrix), whose vee(R - R') is 1e-16 and whose
    rotation vector was 0: the tool stayed where it was, every tick OPTIMAL. It now rolls the shaft and arrives."""
    task, ctrl = _rotated("relative", tmp_path)
    if backend == "native":
        ctrl = vfdsl.compile(task, backend="native")
    start = ctrl.frames(np.array(task.start))["tip"].rotation
    q = np.array(task.start, dtype=float)
    master = np.zeros(6)
    q = q + ctrl.step(q, {"master": master, "clutch": [0.0]})        # engage: the anchors are captured
    master[5] = np.pi
    dq = ctrl.step(q, {"master": master, "clutch": [0.0]})
    assert np.abs(dq).max() > 1e-3, "the tool does not turn toward a goal half a turn away"
    ctrl.reset()
    _, tip = _turned(ctrl, task, [0.0, 0.0, np.pi], ticks=1000, ramp=1)
    assert np.linalg.norm(tip.rotation - _rot([0.0, 0.0, np.pi]) @ start) < 1e-6


def test_a_captured_scale_changes_only_across_a_clutch(tmp_path):
    """scale = k, k captured from the run-time param `gain` on engage: changing gain while following changes
    nothing; after a clutch and a release the new gain scales the master's motion."""
    task, ctrl = _rotated("relative", tmp_path)
    q = np.array(task.start, dtype=float)
    start = ctrl.frames(q)["tip"].position

    def run(master_from, master_to, ticks, params, clutch=0.0):
        nonlocal q
        for k in range(ticks):
            m = np.concatenate([master_from + (master_to - master_from) * min(1.0, (k + 1) / (ticks // 2)), np.zeros(3)])
            q = q + ctrl.step(q, {"master": m, "clutch": [clutch]}, params=params)
        return ctrl.frames(q)["tip"].position

    a = np.array([0.004, 0.0, 0.0])
    run(np.zeros(3), np.zeros(3), 2, None)                     # engaged with gain 0.5
    first = run(np.zeros(3), a, 400, {"gain": 0.25})           # gain changed after engage: the captured 0.5 holds
    assert np.allclose(first - start, 0.5 * CAMERA @ a, atol=1e-6)
    run(a, a, 10, {"gain": 0.25}, clutch=1.0)                  # clutch, release: k = 0.25 from now on
    run(a, a, 2, {"gain": 0.25})
    second = run(a, 2 * a, 400, {"gain": 0.25})
    assert np.allclose(second - first, 0.25 * CAMERA @ a, atol=1e-6)


def test_a_moving_camera_turns_the_masters_motion(tmp_path):
    """The camera (a run-time pose param) turned to yaw 90 deg: the master's +x moves the tool along the world's +y."""
    task, ctrl = _rotated("relative", tmp_path)
    q = np.array(task.start, dtype=float)
    start = ctrl.frames(q)["tip"].position
    camera = {"camera": {"translation": [0, 0, 0], "rpy": [0, 0, np.pi / 2]}}
    for k in range(400):
        m = np.array([0.004 * min(1.0, k / 200), 0, 0, 0, 0, 0])
        q = q + ctrl.step(q, {"master": m, "clutch": [0.0]}, params=camera)
    assert np.allclose(ctrl.frames(q)["tip"].position - start, [0.0, 0.5 * 0.004, 0.0], atol=1e-6)


@pytest.mark.parametrize("change, argument", [
    (("    capture m0 = master\n", ""), "master_anchor"),                                      # captured nowhere now
    (("phase clutched {\n", "phase clutched {\n    capture m1 = master\n"), None),             # (m1 unused: fine)
    (("master_anchor = m0", "master_anchor = camera"), "master_anchor"),                     # a fixed param
])
def test_check_warns_when_an_anchor_is_not_retaken_at_engage(tmp_path, change, argument):
    text = WALL.replace(*change)
    if argument == "master_anchor" and "capture m0" not in text and "master_anchor = m0" in text:
        text = text.replace("phase clutched {\n", "phase clutched {\n    capture m0 = master\n")
    (tmp_path / "t.vf").write_text(text)
    (tmp_path / "t.yaml").write_text(START)
    report = vfdsl.check(vfdsl.load(tmp_path / "t.vf"), samples=0, backend="interpreted")
    found = [f for f in report.findings if f.code == "VF972"]
    if argument is None:
        assert not found
    else:
        line = text.splitlines().index(next(t for t in text.splitlines() if "minimize teleop" in t)) + 1
        assert [f.data["argument"] for f in found] == [argument] and found[0].span.line == line


@pytest.mark.parametrize("change, argument", [
    (("anchor = s0, master_anchor = m0", "anchor = m0, master_anchor = s0"), None),           # both swapped
    (("capture s0 = tip.pose", "capture s0 = master"), "anchor"),                            # the master as anchor
])
def test_check_refuses_an_anchor_captured_from_the_other_side(tmp_path, change, argument):
    # It was a warning (VF972, as for a kept anchor), and the task "sound", while the tool ran off hands-off.
    text = WALL.replace(*change)
    assert text != WALL
    (tmp_path / "t.vf").write_text(text)
    (tmp_path / "t.yaml").write_text(START)
    report = vfdsl.check(vfdsl.load(tmp_path / "t.vf"), samples=0, backend="interpreted")
    found = [f for f in report.findings if f.code == "VF973"]
    assert sorted(f.data["argument"] for f in found) == ([argument] if argument else ["anchor", "master_anchor"])
    assert report.exit_status() == 1 and not [f for f in report.findings if f.code == "VF972"]


def test_the_readout_equals_an_independent_computation(wall):
    """Every tick of a run into the floor, along it and back out: the readout's depth and force equal a NumPy
    computation from the tick's own QP (Controller.problem), Pinocchio's Jacobian, SciPy's rotation vector and the
    previous tick's readout: the rows within 1e-9 of a bound act; their normals (J J' + 1e-10 I)^-1 J a_i; the
    removed rate r = [v_c; w_c] - J dq / dt, v_c = (g - p) / tau, w_c = rotvec(R_g R') / tau; the master's depth
    d = R_c' tau [M (M + 1e-6 I)^-1 r]_linear / scale; s = -(k d + b (d - d_prev) / dt) without its part along d
    (0 at d = 0); the force F_prev + clip(ramp sat(s) - F_prev, rate dt)."""
    from scipy.spatial.transform import Rotation
    from vfdsl.kinematics.robot import Robot
    task, ctrl = wall
    robot = Robot.load("psm6")
    reach = 0.0163 / SCALE
    down = CAMERA.T @ np.array([0.0, 0.0, -(reach + 0.006)])
    masters = master_path(down, down + CAMERA.T @ np.array([0.01, 0.005, 0.0]), np.zeros(3), ticks_per_leg=300,
                          hold=50)
    ctrl.reset()
    q = np.array(task.start, dtype=float)
    dt, damping, ramp, rate = 0.001, 1.0, 0.1, 200.0
    previous, F_prev, engaged, checked = np.zeros(3), np.zeros(3), 0.0, 0
    for k, m in enumerate(masters):
        inputs = {"master": m, "clutch": [0.0]}
        dq = ctrl.step(q, inputs)
        out = ctrl.teleop
        qp = ctrl.problem(q, inputs)                 # this tick's QP (its captures, its activity)
        n = qp.A.shape[1]
        assert n == ctrl.nq
        A, lb, ub = qp.A[n:], qp.lb[n:], qp.ub[n:]
        Ax = A @ dq
        acting = (Ax - lb <= 1e-9) | (ub - Ax <= 1e-9)
        J = robot.frame_jacobian(q, "tool_tip")
        p, R = robot.frame_pose(q, "tool_tip")
        s0, m0 = ctrl.captures["s0"], ctrl.captures["m0"]
        goal = s0[:3] + SCALE * CAMERA @ (m[:3] - m0[:3])
        R_s0 = Rotation.from_euler("xyz", s0[3:]).as_matrix()
        R_m, R_m0 = (Rotation.from_euler("xyz", v).as_matrix() for v in (m[3:], m0[3:]))
        R_goal = CAMERA @ R_m @ R_m0.T @ CAMERA.T @ R_s0
        command = np.concatenate([(goal - p) / TAU, Rotation.from_matrix(R_goal @ R.T).as_rotvec() / TAU])
        removed = command - J @ dq / dt
        normals = np.linalg.solve(J @ J.T + 1e-10 * np.eye(6), J @ A[acting].T)
        M = sum((np.outer(c, c) / (c @ c) for c in normals.T), np.zeros((6, 6)))
        depth = CAMERA.T @ (TAU * (M @ np.linalg.solve(M + 1e-6 * np.eye(6), removed))[:3]) / SCALE
        engaged += dt
        spring = -(STIFFNESS * depth + (damping * (depth - previous) / dt if k else 0.0))
        spring = spring - max(0.0, spring @ depth) * depth / (depth @ depth) if depth @ depth > 0 else 0 * spring
        target = min(1.0, engaged / ramp) * spring * min(1.0, SATURATION / max(np.linalg.norm(spring), 1e-300))
        step = target - F_prev
        force = F_prev + step * min(1.0, rate * dt / max(np.linalg.norm(step), 1e-300))
        assert np.allclose(out.goal, goal, atol=1e-12)
        assert np.allclose(out.depth, depth, rtol=1e-6, atol=1e-10), k
        assert np.allclose(out.force, force, rtol=1e-6, atol=1e-9), k
        checked += bool(acting.any())
        previous, F_prev = out.depth, out.force
        q = q + dq
    assert checked > 200                              # the floor acted on most of the run's ticks


def test_a_master_reach_beyond_any_robot_is_refused(tmp_path):
    """master_reach had no upper bound (a unit slip loaded, and `check`'s workspace check read it)."""
    (tmp_path / "t.vf").write_text(WALL.replace("ramp = 100 ms)", "ramp = 100 ms, master_reach = 1e300)"))
    (tmp_path / "t.yaml").write_text(START)
    with pytest.raises(VfError, match="'master_reach' must be in"):
        vfdsl.load(tmp_path / "t.vf")
