"""``vfdsl simulate`` end to end, on short runs: repeatable JSON, the paper's experiment B within its
stated bounds in an ideal run, the loop-period trend of experiment A, any task with the generic hand, a
plot, and clear errors (file, line, exit status 2, no traceback) for bad scenes and settings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.kinematics.robot import Robot
from vfdsl.sim.runner import make_jobs, run
from vfdsl.sim.scene_file import load_settings

B = str(TASKS_DIR / "paper_b_virtual_rcm.vf")
A = str(TASKS_DIR / "paper_a_follow_curve.vf")


def _simulate(tmp_path, *args, name="run.json") -> dict:
    out = tmp_path / name
    assert main(["simulate", *args, "--quiet", "--json", str(out)]) == 0
    return json.loads(out.read_text())


def test_same_seed_gives_identical_json_and_another_seed_does_not(tmp_path):
    args = [B, "--duration", "2s", "--trials", "2"]
    first = _simulate(tmp_path, *args, name="1.json")
    second = _simulate(tmp_path, *args, name="2.json")
    other = _simulate(tmp_path, *args, "--seed", "7", name="3.json")
    assert (tmp_path / "1.json").read_text() == (tmp_path / "2.json").read_text()
    assert first["seed"] == 1 and [t["seed"] for t in first["trials"]] == [1, 2]
    assert other["metrics"]["tracker_pivot_error_mm"]["mean"] != first["metrics"]["tracker_pivot_error_mm"]["mean"]
    for name in ("pivot_error_mm", "tracker_pivot_error_mm", "tool_angle_error_deg", "tracker_tool_angle_error_deg"):
        assert set(first["metrics"][name]) >= {"mean", "std", "max", "unit", "paper"}
    assert first["settings"]["period"] == 0.01 and first["settings"]["resolution"] == "robot"


def test_ideal_run_of_b_stays_within_the_polytope_plus_the_linearization_bound(tmp_path):
    """Ideal robot (no resolution, latency, lag or tracker), the scene's hand with tremor and drift.

    Polytope: the 4x4 sphere polytope is a cube, corners at sqrt(3) eps; the cone's octagon bounds the
    angle by eps / (cos(gamma) cos(pi/8)). Linearization (docs/results.md): a tick turns the tool by at
    most dth = (w_a + w_b) dt (the two RCM joints' speed limits) and inserts it by at most dl = v dt, so
    the tip, r = 10 mm from the RCM, leaves its first-order position by at most r dth^2 / 2 + dth dl, and
    the tool axis its first-order direction by at most dth^2 / 2."""
    doc = _simulate(tmp_path, B, "--resolution", "off", "--noise", "0", "--duration", "20s", "--trials", "1")
    robot = Robot.load("shr7")
    dt, eps_p, eps_r, gamma = 0.01, 1e-6, 1e-3, math.radians(15)
    limit = dict(zip(robot.joint_names, robot.velocity_limit))
    dth = (limit["rcm_a"] + limit["rcm_b"]) * dt
    dl = limit["insert"] * dt
    pivot_bound = math.sqrt(3) * eps_p + 0.01 * dth ** 2 / 2 + dth * dl
    angle_bound = eps_r / (math.cos(gamma) * math.cos(math.pi / 8)) + dth ** 2 / 2
    metrics = doc["metrics"]
    assert doc["fallback_ticks"] == 0 and doc["uncertified_ticks"] == 0      # every tick's levels certified
    assert metrics["pivot_error_mm"]["max"] <= pivot_bound * 1e3
    assert metrics["tool_angle_error_deg"]["max"] <= math.degrees(angle_bound)
    assert metrics["pivot_error_mm"]["max"] > 0.2 * eps_p * 1e3          # it measured something


def test_longer_loop_period_gives_larger_error_at_the_sharp_turns(tmp_path):
    """Experiment A by the encoders (no tracker, no latency): the tip's worst error to the curve over the
    first sharp turns grows with the period (paper, Fig. 7), and so does a latency past one period."""
    doc = _simulate(tmp_path, A, "--grid", "period=150ms,40ms,10ms", "--latency", "0", "--noise", "0",
                    "--resolution", "off", "--trials", "1", "--duration", "6s")
    worst = [g["metrics"]["tip_error_mm"]["max"] for g in doc["groups"]]
    assert [g["settings"]["period"] for g in doc["groups"]] == [0.15, 0.04, 0.01]
    assert worst[0] > 2 * worst[1] > 4 * worst[2]
    late = _simulate(tmp_path, A, "--grid", "latency=0ms,300ms", "--period", "150ms", "--noise", "0",
                     "--resolution", "off", "--trials", "1", "--duration", "6s", name="late.json")
    on_time, delayed = (g["metrics"]["tip_error_mm"]["max"] for g in late["groups"])
    assert delayed > on_time


def test_any_task_runs_with_the_generic_hand_and_a_plot(tmp_path, capsys):
    plot = tmp_path / "run.png"
    task = str(TASKS_DIR / "lecture_remote_center.vf")
    assert main(["simulate", task, "--duration", "1s", "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "generic hand" in out and "tip_passes_through_error_mm" in out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = _simulate(tmp_path, task, "--duration", "1s")
    assert doc["hand"]["kind"] == "push" and doc["metrics"]["tip_passes_through_error_mm"]["max"] <= 0.5


def test_a_joint_speed_fraction_held_in_a_param_simulates_as_the_same_literal(tmp_path):
    """`require joint_speed(k)` with `param k : number = 0.5`: the generic hand's speed and the joint speed metric
    read k's value (simulate read `.value` of the argument and crashed on a param): the same run as joint_speed(0.5)."""
    head = ('task js\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\ninput f : force\n'
            'minimize track(tip, f, gain = 1 mm/s/N)\n')
    runs = []
    for name, body in [("with_param", "param k : number = 0.5\nrequire joint_speed(k)\n"),
                       ("literal", "require joint_speed(0.5)\n")]:
        (tmp_path / f"{name}.vf").write_text(head.replace("task js", f"task {name}") + body)
        (tmp_path / f"{name}.yaml").write_text("units: mm, deg\nperiod: 10 ms\n"
                                               "start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 20}\n")
        runs.append(_simulate(tmp_path, str(tmp_path / f"{name}.vf"), "--duration", "0.5s", name=f"{name}.json"))
    hands = [{**run["hand"], "assumed": run["hand"]["assumed"].replace("with_param.vf:8", "at")
              .replace("literal.vf:7", "at")} for run in runs]
    assert hands[0] == hands[1] and "joint speed limits of `joint_speed`" in hands[0]["assumed"], hands
    assert runs[0]["metrics"]["joint_speed_mm_s"] == runs[1]["metrics"]["joint_speed_mm_s"]


def test_plate_move_is_absorbed():
    """Fig. 8: after the plate moves 2 mm and tilts, the fixture brings the tip back to the curve."""
    settings = load_settings(vfdsl.load(A), TASKS_DIR / "paper_a_plate_moves.sim.yaml").replace(trials=1, duration=9.0)
    (result,) = run(make_jobs(A, settings, keep_series=True))
    t, error = result.series["t"], result.series["metrics"]["tip_error_mm"]
    jump = np.argmax(t >= 6.0)
    assert error[jump] > 1.0                                    # the plate moved under the tip
    assert np.all(error[jump + 3:] < 0.2)                       # and the fixture brought it back
    assert result.fallback_ticks == 0


BAD_SCENES = [
    ("period: -5 ms\n", 1, "period must be a positive time"),
    ("disturbances:\n  - {at: 1 s, kind: shake, param: pivot}\n", 2, "unknown disturbance 'shake'"),
    ("hand: {input: force, kind: push, direction: [1, 0, 0], magnitude: 1 N}\n", 1,
     "the hand drives input 'force', which task 'paper_b_virtual_rcm' does not declare"),
    ("hand: {input: tau, kind: push, direction: [1, 0, 0], magnitude: 1 N}\n", 1, "needs a force"),
    ("latnecy: 3 ms\n", 1, "unknown key 'latnecy'"),
    ("duration: 3 mm\n", 1, "expected a time"),
    ("metrics:\n  pivot: {error_of: tip stays_near}\n", 2, "no constraint"),
    # values no hand, tracker or disturbance has (a unit mistake, or 1e308 overflowing into non-finite metrics)
    ("hand: {input: tau, kind: turn, axis: [0, 0, 1], magnitude: 1e308 Nmm}\n", 1,
     "a hand's magnitude of 1e+308 Nmm is beyond the 100000 Nmm a simulation scene may give it"),
    ("hand: {input: tau, kind: turn, axis: [0, 0, 1], magnitude: 1 Nmm, drift: 200 Nm}\n", 1,
     "a hand's drift of 200000 Nmm is beyond"),
    ("hand: {input: tau, kind: turn, axis: [0, 0, 1], magnitude: 1 Nmm, tremor_band: [8, 1e308]}\n", 1,
     "a tremor band up to 1e+308 Hz is beyond the 1000 Hz"),
    ("units: mm\ntracker: {noise: 1e308}\n", 2, "a tracker noise of 1e+308 mm RMS is beyond the 10 mm"),
    ("latency: 1e308 s\n", 1, "a latency of 1e+308 s is beyond the 10 s a simulated robot may have"),   # (it ran:
    ("servo_lag: 11 s\n", 1, "a servo lag of 11 s is beyond the 10 s"),             # "latency inf ms", no motion)
    ("units: mm\ntracker: {marker_distance: 1e308}\n", 2, "marker_distance must be from 1 mm to 1000 mm, got 1e+308 mm"),
    ("units: mm\ndisturbances:\n  - {at: 1 s, kind: push_tool, frame: tip, by: [1e308, 0, 0]}\n", 3,
     "a push_tool displacement of 1e+308 mm is beyond the 100 mm"),
    ("units: mm\ndisturbances:\n  - {at: 1 s, kind: move_param, param: pivot, translate: [0, 1e300, 1e300]}\n", 3,
     "a move_param translation of 1.41421e+300 mm is beyond the 100 mm"),
]


@pytest.mark.parametrize("text, line, message", BAD_SCENES)
def test_bad_scene_is_a_clear_error_with_file_and_line(tmp_path, capsys, text, line, message):
    scene = tmp_path / "bad.sim.yaml"
    scene.write_text(text)
    assert main(["simulate", B, "--scene", str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{scene}:{line}:" in err and message in err and "Traceback" not in err


@pytest.mark.parametrize("args, message", [
    (["--period=-5ms"], "--period -5ms: period must be a positive time"),
    (["--latency", "3 deg"], "expected a time"),
    (["--grid", "colour=1,2"], "unknown setting 'colour'"),
    (["--grid", "period"], "write NAME=V1,V2"),
    (["--trials", "0"], "trials must be a positive whole number"),
    (["--json", "no/such/dir/out.json"], "cannot write no/such/dir/out.json: no directory"),
    (["--scene", "no_such.sim.yaml"], "simulation scene not found: no_such.sim.yaml"),
    (["--noise", "1e308m"], "a tracker noise of 1e+308 m RMS is beyond the 10 mm"),
    (["--noise", "0.2"], "bare numbers on the command line are SI (m, s): give the unit, e.g. 0.2mm"),
    (["--latency", "20"], "--latency 20: a latency of 20 s is beyond the 10 s a simulated robot may have"),
    # the controller's dt range, before the run (it was the Controller.step error about dt, from the first tick)
    (["--period", "2s"], "a period of 2000 ms is outside [0.1 ms, 100 ms], the periods task 'paper_b_virtual_rcm' "
                         "steps at (1/100 to 10 times its scene's period, 10 ms)"),
    (["--grid", "period=10ms,0.05ms"], "--grid period=5e-05: a period of 0.05 ms is outside [0.1 ms, 100 ms]"),
    (["--period", "0.001ms"], "the shortest control period is 0.01 ms"),        # (said "10 us": no unit 'us')
    (["--grid", "servo_lag=0,1e308"], "--grid servo_lag=1e308: a servo lag of 1e+308 s is beyond the 10 s"),
])
def test_bad_setting_on_the_command_line_is_a_clear_error(capsys, args, message):
    assert main(["simulate", B, "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_an_output_that_is_a_fifo_without_a_reader_is_refused_not_waited_on(tmp_path):
    """--json, --csv, --trace and --plot to a FIFO nobody reads: a clear error at once (opening it for writing used
    to wait for a reader forever)."""
    import os
    import subprocess
    import sys
    for flag, name in (("--json", "out.json"), ("--plot", "out.png")):
        fifo = tmp_path / name
        os.mkfifo(fifo)
        result = subprocess.run([sys.executable, "-m", "vfdsl.cli", "simulate", B, "--quiet", flag, str(fifo)],
                                capture_output=True, text=True, timeout=120)
        assert result.returncode == 2 and f"cannot write {fifo}" in result.stderr, result.stderr


def test_an_output_that_is_an_input_or_another_output_is_refused_before_the_run(tmp_path, capsys):
    """--json, --csv, --trace or --plot naming the task, its scene or the simulation scene would destroy it, and two
    outputs naming one file would replace each other: refused, exit 2, every file as it was (--plot on the task used
    to be refused by its suffix alone, --json on it replaced the task with JSON)."""
    import shutil
    for name in ("paper_b_virtual_rcm.vf", "paper_b_virtual_rcm.yaml"):
        shutil.copy(TASKS_DIR / name, tmp_path / name)
    shutil.copytree(TASKS_DIR / "library", tmp_path / "library")
    task, scene, sim = (tmp_path / "paper_b_virtual_rcm.vf", tmp_path / "paper_b_virtual_rcm.yaml",
                        tmp_path / "b.sim.yaml")
    sim.write_text("duration: 0.1 s\n")
    (tmp_path / "link.csv").symlink_to(scene)
    library = tmp_path / "library" / "fixtures.vf"
    before = {path: path.read_bytes() for path in (task, scene, sim, library)}
    for args, message in (
            (["--json", str(task)], f"--json {task} is the task file: writing the output there would destroy it"),
            (["--csv", str(tmp_path / "link.csv")], "is the task's scene file"),
            (["--json", str(tmp_path / "." / "b.sim.yaml")], "is the simulation scene"),
            (["--plot", str(task)], "is the task file"),
            (["--json", str(library)], "is a file the task imports"),
            (["--json", str(tmp_path / "x"), "--csv", str(tmp_path / "x")], "name the same file: one output would "
                                                                           "replace the other"),
            (["--trace", str(tmp_path / "x.csv"), "--csv", str(tmp_path / "x.csv")], "name the same file")):
        assert main(["simulate", str(task), "--scene", str(sim), "--quiet", *args]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, err
    assert {path: path.read_bytes() for path in before} == before
    assert not (tmp_path / "x").exists() and not (tmp_path / "x.csv").exists()


def test_an_output_that_is_the_robots_urdf_or_a_mesh_file_is_refused(tmp_path, capsys):
    """The robot's URDF file and a mesh param's file are read too: an output naming one of them is refused before the
    run, the file as it was (`--json channel.stl` replaced the mesh with JSON, `--csv arm.urdf` the robot)."""
    import shutil
    shutil.copytree(TASKS_DIR / "anatomy", tmp_path / "anatomy")
    shutil.copytree(TASKS_DIR / "library", tmp_path / "library")
    shutil.copy(Path(vfdsl.__file__).parent / "robots" / "shr7.urdf", tmp_path / "arm.urdf")
    source = (TASKS_DIR / "sinus_channel.vf").read_text()
    assert 'urdf "shr7"' in source
    (tmp_path / "t.vf").write_text(source.replace('urdf "shr7"', 'urdf "arm.urdf"'))
    shutil.copy(TASKS_DIR / "sinus_channel.yaml", tmp_path / "t.yaml")
    mesh, urdf = tmp_path / "anatomy" / "channel.stl", tmp_path / "arm.urdf"
    before = {path: path.read_bytes() for path in (mesh, urdf)}
    for args, message in ((["--json", str(mesh)], "is the mesh file of param channel"),
                          (["--csv", str(urdf)], "is the URDF file of robot shr")):
        assert main(["simulate", str(tmp_path / "t.vf"), "--duration", "0.1s", "--quiet", *args]) == 2
        err = capsys.readouterr().err
        assert message in err and "writing the output there would destroy it" in err and "Traceback" not in err, err
    assert {path: path.read_bytes() for path in before} == before


def test_a_scene_without_start_is_refused_naming_it(tmp_path, capsys):
    """No `start:` in the task's scene: refused before the run, naming the scene (the robot started at zero clipped
    into its joint limits, and the fixture then moved it 228 mm on its own)."""
    task, scene = tmp_path / "t.vf", tmp_path / "t.yaml"
    task.write_text((TASKS_DIR / "lecture_remote_center.vf").read_text())
    own = (TASKS_DIR / "lecture_remote_center.yaml").read_text().splitlines(keepends=True)
    scene.write_text("".join(line for line in own if not line.startswith("start:")))
    assert main(["simulate", str(task), "--duration", "0.1s", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"its scene {scene} has no `start:`" in err and "give the scene `start: [...]`" in err, err


def test_readme_first_command_simulates_experiment_b(capsys, monkeypatch):
    """The README's quick start: install, then `vfdsl simulate` of experiment B, which needs nothing else."""
    from conftest import REPO

    readme = (REPO / "README.md").read_text()
    quick_start = readme[readme.index("## Quick start"):]
    commands = [line.strip() for line in quick_start.splitlines() if line.startswith("    python3 -m venv")]
    assert commands[0].endswith("pip install . && vfdsl simulate tasks/paper_b_virtual_rcm.vf")
    assert commands[1].endswith('pip install ".[test]" && pytest')
    monkeypatch.chdir(REPO)
    argv = commands[0].split("&& vfdsl ")[1].split()
    assert main(argv) == 0
    out = capsys.readouterr().out
    for name in ("pivot_error_mm", "tracker_pivot_error_mm", "tool_angle_error_deg", "0.23 ± 0.11"):
        assert name in out


def test_hand_toward_a_plane_and_a_push_through_it(tmp_path):
    """The lecture's forbidden half-space: a hand pushing the tip toward the wall 10 mm below (with tremor)
    reaches it and never enters it (above's error 0); a push of 0.5 mm through the wall at 3 s is an error of 0.5 mm, and the fixture moves
    the tip back out within two ticks."""
    scene = tmp_path / "wall.sim.yaml"
    scene.write_text("units: mm, deg\nduration: 4 s\n"
                     "hand: {input: f, kind: toward, target: wall, magnitude: 10 N, tremor: 1 N}\n"
                     "disturbances:\n  - {at: 3 s, kind: push_tool, frame: tip, by: [0, 0, -0.5]}\n")
    task = str(TASKS_DIR / "lecture_forbidden_half_space.vf")
    settings = load_settings(vfdsl.load(task), scene)
    (result,) = run(make_jobs(task, settings, keep_series=True))
    t, error = result.series["t"], result.series["metrics"]["tip_above_error_mm"]
    z = result.series["p"]["tip"][:, 2]
    push = np.argmax(t >= 3.0)
    assert z[:push].min() == pytest.approx(0.270, abs=1e-6)     # the hand brought the tip onto the wall
    assert np.all(error[:push] < 1e-6)
    assert error[push] == pytest.approx(0.5, abs=1e-3)
    assert error[push + 1] < error[push]                        # out at the joints' speed limits: z stage and
    assert np.all(error[push + 2:] < 1e-6)                      # insertion, 0.2 mm a tick each
    assert result.fallback_ticks >= 1                           # the least-violation step did it


def test_unreachable_cluster_is_a_clear_error(capsys, monkeypatch):
    from vfdsl import limits

    monkeypatch.setattr(limits, "CONNECT_TIMEOUT", 1.0)
    assert main(["simulate", B, "--quiet", "--duration", "0.1s", "--cluster", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "cannot reach a Dask scheduler at 'tcp://127.0.0.1:9'" in err and "Traceback" not in err


@pytest.mark.parametrize("address, said", [
    ("", "'' is not the address of a Dask scheduler: it is empty"),                     # ran locally, as if not given
    ("foo", "'foo' is not the address of a Dask scheduler (missing port number"),        # 'foo' answers, but not as ...
    ("tcp://127.0.0.1:99999", "(port 99999: a port is 1 to 65535)"),
    ("xyz://host:8786", "unknown address scheme 'xyz'"),
])
def test_a_cluster_address_that_is_not_one_is_refused_before_connecting(capsys, address, said):
    assert main(["simulate", B, "--quiet", "--duration", "0.1s", "--cluster", address]) == 2
    err = capsys.readouterr().err
    assert said in err and "hint: an address like tcp://host:8786" in err and "Traceback" not in err, err


def test_experiment_a_is_scored_by_the_distance_to_the_curve_and_the_hand_stops_at_its_end():
    """Experiment A's full trial (24 s at 150 ms, the scene's hand with tremor and drift): the tip error is the
    distance to the curve itself, recomputed here by a dense search of the curve mapped to the world by the plate
    pose; the hand brings the tip to the curve's end and holds it there, so it never runs past the end."""
    from scipy.interpolate import make_interp_spline
    from scipy.spatial.transform import Rotation

    task = vfdsl.load(A)
    settings = load_settings(task, TASKS_DIR / "paper_a_follow_curve.sim.yaml").replace(trials=1)
    (result,) = run(make_jobs(A, settings, keep_series=True))
    plate, path = task.param("plate").value, task.param("path").value
    R, t = Rotation.from_euler("xyz", plate.rpy).as_matrix(), np.asarray(plate.translation)
    points = np.asarray(path.points)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    dense = make_interp_spline(s, points, k=path.degree)(np.linspace(0, s[-1], 200_001)) @ R.T + t
    tip = result.series["p"]["tip"]
    brute = np.array([np.sqrt(np.min(np.sum((dense - x) ** 2, axis=1))) for x in tip])
    np.testing.assert_allclose(result.series["metrics"]["tip_error_mm"], brute * 1e3, atol=2e-4)
    end, tangent = dense[-1], (dense[-1] - dense[-2]) / np.linalg.norm(dense[-1] - dense[-2])
    near = np.linalg.norm(tip - end, axis=1) < 1e-3                  # the tip within 1 mm of the end
    assert near[-4:].all()                          # the hand got there before the trial ended
    beyond = (tip[near] - end) @ tangent
    assert beyond.max() < 0.05e-3                   # never more than 0.05 mm past the end (was 0.4-0.67 mm)
    assert np.linalg.norm(tip[-1] - end) < 0.1e-3   # at the end when the trial stops
    # and on the curve there, not on its tangent beyond it (0.4-0.67 mm before): 11 um measured, within the
    # trial's own error at 150 ms with tremor (27 um mean)
    assert brute[-3:].max() < 0.05e-3


def test_events_after_the_end_of_the_run_are_warned_at_their_line(capsys):
    """A run shortened below a scene's event times: each disturbance, step and ramp that would start at or after
    the end is named with its file:line:col (it never happens); the run itself goes on, and a run long enough,
    or a sweep whose longest duration reaches the event, warns nothing."""
    vessel = str(TASKS_DIR / "breathing_vessel.vf")
    assert main(["simulate", vessel, "--quiet", "--duration", "0.5s"]) == 0
    err = capsys.readouterr().err
    assert "breathing_vessel.sim.yaml:20:5: warning: the step motion of param 'vessel' (from 6 s) starts after " \
           "the run's 0.5 s" in err
    assert "sine" not in err                               # a sine acts from the start
    plate = ["simulate", str(TASKS_DIR / "paper_a_follow_curve.vf"), "--scene",
             str(TASKS_DIR / "paper_a_plate_moves.sim.yaml"), "--quiet", "--trials", "1"]
    assert main([*plate, "--duration", "6s"]) == 0
    assert "paper_a_plate_moves.sim.yaml:21:5: warning: the move_param disturbance at 6 s" in capsys.readouterr().err
    assert main([*plate, "--grid", "duration=1s,6.2s"]) == 0
    assert "warning" not in capsys.readouterr().err


def _finite(text: str) -> dict:
    """A JSON document read strictly: NaN and Infinity (which json.dumps writes for non-finite floats) refused."""
    def refuse(constant):
        raise AssertionError(f"non-finite value in the JSON: {constant}")
    return json.loads(text, parse_constant=refuse)


EXTREMES = [   # every number a scene may hold, at an extreme, on lecture_forbidden_half_space (force f, plane wall)
    "latency: 1e308 s", "servo_lag: 1e308 s", "latency: 1e-308 s", "servo_lag: 1e-308 s", "period: 1e-308 s",
    "duration: 1e308 s", "trials: 1e308", "seed: 1e308",
    "tracker: {noise: 1e-308 mm, marker_distance: 1e-308 mm}",
    "hand: {input: f, kind: push, direction: [1e308, 1e308, 0], magnitude: 5 N}",
    "hand: {input: f, kind: push, direction: [1e-308, 0, 1e-308], magnitude: 5 N}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 1e308 N}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, tremor: 1e308 N}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, drift: 1e308 N}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, tremor: 1 N, tremor_band: [1e-308, 1e-308]}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, drift: 1 N, drift_time: 1e308 s}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, drift: 1 N, drift_time: 1e-308 s}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, reaction: 1e308 s}",
    "hand: {input: f, kind: push, direction: [1, 0, 0], magnitude: 5 N, reaction: 1e-308 s}",
    "disturbances: [{at: 1e308 s, kind: push_tool, frame: tip, by: [1, 0, 0]}]",
    "disturbances: [{at: 0.05 s, kind: push_tool, frame: tip, by: [1e-308, 0, 0]}]",
    "disturbances: [{at: 0.05 s, kind: move_param, param: wall, translate: [0, 0, 1e308]}]",
    "motions: [{param: wall, kind: sine, amplitude: [0, 0, 1e308], frequency: 1 Hz}]",
    "motions: [{param: wall, kind: sine, amplitude: [0, 0, 1], frequency: 1e308 Hz}]",
    "motions: [{param: wall, kind: sine, amplitude: [0, 0, 1], frequency: 1 Hz, phase: 1e308 deg}]",
    "motions: [{param: wall, kind: ramp, start: 0 s, end: 1e308 s, offset: [0, 0, 1]}]",
    "motions: [{param: wall, kind: step, at: 1e-308 s, offset: [0, 0, 1e-308]}]",
    "metrics: {wall: {error_of: tip above, paper: {encoders: [1e308, 1e308]}}}",
]


@pytest.mark.parametrize("line", EXTREMES)
def test_an_extreme_scene_value_is_refused_at_its_line_or_every_figure_stays_finite(tmp_path, capsys, line):
    """Each number of a scene at an extreme (1e308 or 1e-308 in its unit): the run is refused at the value's line
    (exit 2, no traceback), or it runs and its --json holds finite numbers only and no line of its report ends in
    an empty phrase."""
    scene, out = tmp_path / "x.sim.yaml", tmp_path / "out.json"
    scene.write_text(f"units: mm, deg\nduration: 0.2 s\n{line}\n")
    status = main(["simulate", str(TASKS_DIR / "lecture_forbidden_half_space.vf"), "--scene", str(scene),
                   "--json", str(out)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    if status == 2:
        assert f"{scene}:3:" in captured.err, captured.err
        return
    assert status == 0
    _finite(out.read_text())
    assert not [text for text in captured.out.splitlines() if text.rstrip().endswith(":")], captured.out


def test_a_part_the_hand_never_commands_is_left_out_and_no_phrase_is_empty(tmp_path, capsys):
    """A twist-driven task (lecture_remote_center): a turning hand commands the angular part only, which is the
    only part reported (the linear one was NaN in --json, and left the report's phrase empty when both were); a
    hand of magnitude 0 commands nothing, and the report says so."""
    task = TASKS_DIR / "lecture_remote_center.vf"
    for hand, said in (("{input: stick, kind: turn, axis: [0, 0, 1], magnitude: 10 deg/s}",
                        "the robot made: track(tip) angular "),
                       ("{input: stick, kind: push, direction: [1, 0, 0], magnitude: 0 mm/s}",
                        "the hand commanded no motion of a tracked part")):
        scene, out = tmp_path / "x.sim.yaml", tmp_path / "out.json"
        scene.write_text(f"units: mm, deg\nduration: 0.5 s\nhand: {hand}\n")
        assert main(["simulate", str(task), "--scene", str(scene), "--json", str(out)]) == 0
        printed = capsys.readouterr().out
        assert said in printed
        fractions = _finite(out.read_text())["motion"]["commanded_fraction"]
        assert list(fractions) == (["track(tip) angular"] if "turn" in hand else [])
