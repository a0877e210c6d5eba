"""``vfdsl check``: for each finding, a small task that triggers it and one that does not; the numbers
behind the findings against independent computations; the command line (exit codes, JSON)."""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import TASKS_DIR, run_cli

import vfdsl
from vfdsl.check import check, polytope
from vfdsl.compiler.polytope import directions, geometry
from vfdsl.check.report import CODES, Severity
from vfdsl.compiler.geometry import sphere_directions
from vfdsl.runtime.qp import StepStatus

# A sound probe task on the built-in Steady-Hand-like robot: at the start (insertion 10 mm) the tip is at
# (0, 0, 290) mm and the tool axis points up (+z).
PROBE = """\
task probe
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param target : point = [0, 0, 290]
minimize track(tip, f, gain = 1 mm/s/N)
minimize damping() weight 1e-6
require tip stays_at(target) within 0.05 resolution 12x12
require joint_limits()
require joint_speed()
"""
SCENE = """\
units: mm, deg
period: 10 ms
start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 10}
"""
STAYS_AT = "require tip stays_at(target) within 0.05 resolution 12x12"


def write_probe(tmp_path: Path, text: str = PROBE, scene: str = SCENE) -> Path:
    (tmp_path / "probe.yaml").write_text(scene)
    (tmp_path / "probe.vf").write_text(text)
    return tmp_path / "probe.vf"


def probe(tmp_path: Path, text: str = PROBE, scene: str = SCENE) -> vfdsl.Task:
    return vfdsl.load(write_probe(tmp_path, text, scene))


def codes(task: vfdsl.Task, **options) -> dict[str, list]:
    """name -> the findings of that name (a short random walk unless ``samples`` is given)."""
    found: dict[str, list] = {}
    for f in check(task, backend="interpreted", **{"samples": 20, **options}).findings:
        found.setdefault(f.name, []).append(f)
    return found


def with_constraint(task: vfdsl.Task, index: int, **update) -> vfdsl.Task:
    """The task with constraint ``index`` changed (for what the front end refuses in a file)."""
    constraints = list(task.constraints)
    constraints[index] = constraints[index].model_copy(update=update)
    return task.model_copy(update={"constraints": constraints})


def test_the_probe_task_is_sound(tmp_path):
    report = check(probe(tmp_path), backend="interpreted")
    assert [f.severity for f in report.findings if f.severity != Severity.NOTE] == [], report.render_text()
    assert report.exit_status() == 0 and report.exit_status(strict=True) == 0


def test_codes_are_unique_and_named():
    assert len(set(CODES.values())) == len(CODES)
    assert all(code.startswith("VF") and len(code) == 5 for code in CODES.values())


# ------------------------------------------------------------------------------------------ polytopes

def _brute_force_circumradius(U: np.ndarray) -> float:
    """Farthest vertex of {v : U v <= 1}: every d-subset of facet planes, kept if it satisfies all facets."""
    d = U.shape[1]
    best = 0.0
    for rows in itertools.combinations(range(len(U)), d):
        M = U[list(rows)]
        if abs(np.linalg.det(M)) < 1e-12:
            continue
        v = np.linalg.solve(M, np.ones(d))
        if np.all(U @ v <= 1 + 1e-9):
            best = max(best, float(np.linalg.norm(v)))
    return best


@pytest.mark.parametrize("resolution", [(3, 3), (4, 4), (5, 5), (6, 6), (8, 8), (4, 8), (8, 4), (3, 7)])
def test_sphere_circumradius_matches_vertex_enumeration(resolution):
    g = geometry("sphere", resolution)
    assert g.bounded
    assert g.unique == len(sphere_directions(*resolution))
    assert g.circumradius == pytest.approx(_brute_force_circumradius(sphere_directions(*resolution)), rel=1e-9)


def test_paper_4x4_is_a_cube():
    g = geometry("sphere", (4, 4))
    assert (g.listed, g.unique) == (16, 6)
    assert g.circumradius == pytest.approx(math.sqrt(3))


@pytest.mark.parametrize("n", [3, 4, 5, 8, 13])
def test_polygon_circumradius_is_one_over_cos_pi_over_n(n):
    assert geometry("polygon", (n,)).circumradius == pytest.approx(1 / math.cos(math.pi / n))


@pytest.mark.parametrize("shape, resolution", [("sphere", (2, 2)), ("sphere", (2, 6)), ("sphere", (6, 2)),
                                               ("polygon", (2,)), ("polygon", (1,))])
def test_flat_or_two_sided_polytopes_are_unbounded(shape, resolution):
    g = geometry(shape, resolution)
    assert not g.bounded and g.circumradius == math.inf
    # independent: some direction w has u . w <= 0 for every facet, so t w is admitted for every t
    U = directions(shape, resolution)
    rng = np.random.default_rng(0)
    W = rng.normal(size=(20000, U.shape[1]))
    W = np.vstack([W, np.eye(U.shape[1]), -np.eye(U.shape[1])])
    assert np.any(np.all(W @ U.T <= 1e-12, axis=1))


@pytest.mark.parametrize("overshoot", [0.5, 0.1, 0.05])
def test_smallest_resolution_meets_the_overshoot_and_nothing_smaller_does(overshoot):
    best = polytope.smallest_resolution("sphere", overshoot)
    assert best.overshoot <= overshoot
    for n in range(3, polytope.SEARCH_LIMIT + 1):
        for m in range(3, polytope.SEARCH_LIMIT + 1):
            if len(sphere_directions(n, m)) < best.unique:
                assert geometry("sphere", (n, m)).overshoot > overshoot
    polygon = polytope.smallest_resolution("polygon", overshoot)
    assert polygon.overshoot <= overshoot < geometry("polygon", (polygon.resolution[0] - 1,)).overshoot


def test_circumradius_is_reached_by_the_compiled_rows(tmp_path):
    """The cube's corner sqrt(3) eps from the target satisfies every row the controller enforces."""
    task = probe(tmp_path, PROBE.replace("resolution 12x12", "resolution 4x4"))
    ctrl = vfdsl.compile(task, backend="interpreted")
    qp = ctrl.problem(task.start, {"f": [0, 0, 0]})
    rows = [i for i, label in enumerate(qp.labels) if label.startswith("stays_at")]
    robot = ctrl.assembled.context.robot
    J = robot.frame_jacobian(task.start, "tool_tip")[:3]
    eps = 0.05e-3
    for corner in itertools.product([-1, 1], repeat=3):
        v = eps * np.array(corner, dtype=float)                    # the error after the step: a cube corner
        p, _ = robot.frame_pose(task.start, "tool_tip")
        dq = np.linalg.lstsq(J, v - (p - [0, 0, 0.29]), rcond=None)[0]
        A = qp.A[rows, :ctrl.nq]
        assert np.all(A @ dq >= qp.lb[rows] - 1e-12)               # admitted by every facet
        assert np.linalg.norm(v) == pytest.approx(geometry("sphere", (4, 4)).circumradius * eps)


def test_unbounded_polytope_is_an_error(tmp_path):
    task = probe(tmp_path)
    assert "polytope-unbounded" not in codes(task)
    found = codes(with_constraint(task, 0, resolution=[2, 2]))["polytope-unbounded"]
    assert found[0].severity == Severity.ERROR and found[0].span.line == 9


def test_overshoot_warning_names_the_circumradius_and_a_resolution(tmp_path):
    task = probe(tmp_path, PROBE.replace("resolution 12x12", "resolution 4x4"))
    found = codes(task)["polytope-overshoot"][0]
    assert found.severity == Severity.WARNING and found.span.line == 9
    assert "86.6 um" in found.message and "73%" in found.message            # sqrt(3) * 50 um
    assert found.data["worst"] == pytest.approx(math.sqrt(3) * 0.05e-3)
    best = polytope.smallest_resolution("sphere", 0.10)
    assert f"resolution {best.label}" in found.suggestion
    assert "polytope-overshoot" not in codes(task, overshoot=0.8)
    assert "polytope-overshoot" not in codes(probe(tmp_path))                 # 12x12: 6.9%


def test_repeated_directions_note(tmp_path):
    assert codes(probe(tmp_path))["polytope-repeated-directions"][0].data["facets"] == 62
    assert "polytope-repeated-directions" not in codes(probe(tmp_path, PROBE.replace("12x12", "5x9")))


def test_bounds_table_in_task_units(tmp_path):
    text = PROBE.replace(STAYS_AT, "require tip within_distance(target, 34.5 mm) resolution 8x8")
    report = check(probe(tmp_path, text), backend="interpreted")
    [bound] = report.bounds
    assert (bound.resolution, bound.facets) == ("8x8", 26)
    assert bound.worst == pytest.approx(0.0345 * geometry("sphere", (8, 8)).circumradius)
    assert "34.5 mm" in report.render_text() and "39.98 mm" in report.render_text()


# ------------------------------------------------------------------------------------------ tolerances

def test_nonpositive_tolerance_is_an_error(tmp_path):
    task = probe(tmp_path)
    assert "tolerance-nonpositive" not in codes(task)
    assert codes(with_constraint(task, 0, tolerance=-1e-6))["tolerance-nonpositive"][0].severity == Severity.ERROR


def test_implausible_tolerance_is_a_warning(tmp_path):
    found = codes(probe(tmp_path, PROBE.replace("within 0.05 resolution", "within 50 resolution")))
    assert "a unit slip" in found["tolerance-implausible"][0].message
    assert "tolerance-implausible" not in codes(probe(tmp_path))


def test_tolerance_below_the_joint_resolution(tmp_path):
    found = codes(probe(tmp_path, PROBE.replace("within 0.05 resolution", "within 0.001 resolution")))
    finding = found["tolerance-below-resolution"][0]
    # independent: half a 10 um step of each joint along the worst facet, from Pinocchio's Jacobian
    robot = vfdsl.compile(probe(tmp_path), backend="interpreted").assembled.context.robot
    start = np.array([0, 0, 0, 0, 0, 0, 0.01])
    J = robot.frame_jacobian(start, "tool_tip")[:3]
    U = sphere_directions(12, 12)
    expected = 0.5 * np.max(np.abs(U @ J) @ robot.resolution)
    assert finding.data["realizable"] == pytest.approx(expected)
    assert finding.data["tolerance"] == pytest.approx(1e-6) and 1e-6 < expected
    assert "tolerance-below-resolution" not in codes(probe(tmp_path))


def test_restore_takes_many_ticks_at_slow_joint_speeds(tmp_path):
    slow = PROBE.replace("require joint_speed()", "require joint_speed(fraction = 0.001)")
    task = probe(tmp_path, slow)
    finding = codes(task)["tolerance-restore-ticks"][0]
    # independent: over the box |dq_k| <= v_k, max (u J) dq = sum_k |u J_k| v_k (closed form, no LP)
    robot = vfdsl.compile(task, backend="interpreted").assembled.context.robot
    J = robot.frame_jacobian(task.start, "tool_tip")[:3]
    v = 0.001 * robot.velocity_limit * 0.01
    expected = np.min(np.abs(sphere_directions(12, 12) @ J) @ v)
    assert finding.data["reach_per_tick"] == pytest.approx(expected, rel=1e-6)
    assert finding.data["ticks"] == math.ceil(0.05e-3 / expected) > 10
    assert finding.severity == Severity.WARNING
    assert "tolerance-restore-ticks" not in codes(probe(tmp_path))


# ------------------------------------------------------------------------------------------ feasibility

def test_infeasible_start_names_an_irreducible_subset(tmp_path):
    """The target 10 mm away, the joints limited to 0.2 mm per tick: stays_at and joint_speed conflict;
    joint_limits is not part of the conflict."""
    far = PROBE.replace("param target : point = [0, 0, 290]", "param target : point = [0, 0, 280]")
    found = codes(probe(tmp_path, far))["start-infeasible"][0]
    assert found.severity == Severity.ERROR
    assert sorted(c["line"] for c in found.data["conflict"]) == [9, 11]
    assert found.data["margin"] < 0
    # a second solver agrees: the compiled controller (DAQP) cannot satisfy its rows at the start
    ctrl = vfdsl.compile(probe(tmp_path, far), backend="interpreted")
    ctrl.step(ctrl.task.start, {"f": [0, 0, 0]})
    assert ctrl.violations() and ctrl.status & StepStatus.LEAST_VIOLATION
    assert "start-infeasible" not in codes(probe(tmp_path))


def test_without_joint_speed_the_start_is_judged_within_the_urdf_velocity_limits(tmp_path):
    """Without ``require joint_speed()`` the controller still holds every tick to the URDF's velocity limits
    (joint_speed()'s own bound, fraction 1), so the target 10 mm away is as unreachable in one tick: the same margin,
    the conflict now stays_at alone, said to be within those limits; the compiled controller agrees (least
    violation), and so do the sampled states' margins."""
    far = PROBE.replace("param target : point = [0, 0, 290]", "param target : point = [0, 0, 280]")
    stated = codes(probe(tmp_path, far))["start-infeasible"][0]
    implicit_task = probe(tmp_path, far.replace("require joint_speed()\n", ""))
    found = codes(implicit_task, samples=3)
    implicit = found["start-infeasible"][0]
    assert implicit.data["margin"] == pytest.approx(stated.data["margin"], rel=1e-9)
    assert [c["line"] for c in implicit.data["conflict"]] == [9]
    assert "within the URDF's velocity limits (the task states no joint_speed)" in implicit.message
    assert "URDF velocity limit times the period" in implicit.suggestion
    assert "URDF" not in stated.message
    assert "within the URDF's velocity limits" in found["sampled-infeasible"][0].message
    ctrl = vfdsl.compile(implicit_task, backend="interpreted")
    ctrl.step(implicit_task.start, {"f": [0, 0, 0]})
    assert ctrl.violations() and ctrl.status & StepStatus.LEAST_VIOLATION
    # a period 50 times longer lets the joints reach it in one tick, as the controller does
    slow = probe(tmp_path, far.replace("require joint_speed()\n", ""), SCENE.replace("10 ms", "500 ms"))
    assert "start-infeasible" not in codes(slow, samples=0)
    ctrl = vfdsl.compile(slow, backend="interpreted")
    ctrl.step(slow.start, {"f": [0, 0, 0]})
    assert not ctrl.violations() and not ctrl.status & StepStatus.LEAST_VIOLATION


# ------------------------------------------------------------------------------------------ the command

def test_cli_exit_codes_and_json(tmp_path):
    probe(tmp_path, PROBE.replace("resolution 12x12", "resolution 4x4"))
    proc = run_cli("check", str(tmp_path / "probe.vf"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "warning VF102 polytope-overshoot" in proc.stdout and "^^^" in proc.stdout
    assert proc.stdout.rstrip().splitlines()[-1].startswith("probe: sound")
    assert run_cli("check", str(tmp_path / "probe.vf"), "--strict").returncode == 1
    data = json.loads(run_cli("check", str(tmp_path / "probe.vf"), "--json").stdout)
    assert data["schema"] == 1 and data["exit_status"] == 0
    [overshoot] = [f for f in data["findings"] if f["code"] == "VF102"]
    assert overshoot["location"]["line"] == 9 and overshoot["severity"] == "warning"
    probe(tmp_path, PROBE.replace("[0, 0, 290]", "[0, 0, 280]"))
    proc = run_cli("check", str(tmp_path / "probe.vf"))
    assert proc.returncode == 1 and "NOT SOUND" in proc.stdout


def test_cli_backend_interpreted_builds_nothing_and_finds_the_same(tmp_path, monkeypatch):
    """--backend interpreted: the closed-loop analyses run in CasADi, no library is built (an empty cache stays
    empty), and the findings are the default backend's (codes, severities, lines: the summary's worst tick can differ
    where states tie to rounding, 0.707 at ticks 11 and 98); a backend that is not one is a usage error."""
    probe(tmp_path, PROBE.replace("resolution 12x12", "resolution 4x4"))
    task = str(tmp_path / "probe.vf")
    native = json.loads(run_cli("check", task, "--json").stdout)
    monkeypatch.setenv("VFDSL_CACHE", str(tmp_path / "empty"))
    proc = run_cli("check", task, "--json", "--backend", "interpreted")
    assert proc.returncode == 0, proc.stderr
    interpreted = json.loads(proc.stdout)
    assert not (tmp_path / "empty").exists() or not any((tmp_path / "empty").iterdir())
    assert [(f["code"], f["severity"], f["location"]) for f in interpreted["findings"]] == \
        [(f["code"], f["severity"], f["location"]) for f in native["findings"]]
    proc = run_cli("check", task, "--backend", "fast")
    assert proc.returncode == 2 and "invalid choice: 'fast'" in proc.stderr


def test_cli_usage_and_front_end_errors_exit_2(tmp_path):
    write_probe(tmp_path, PROBE.replace("stays_at(target)", "stays_at(tagret)"))
    proc = run_cli("check", str(tmp_path / "probe.vf"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and "unknown" in proc.stderr
    assert run_cli("check", str(tmp_path / "probe.vf"), "--overshoot", "lots").returncode == 2


def test_a_bare_overshoot_is_a_percentage_as_pct_says(tmp_path):
    """--overshoot 5 is 5%, as --overshoot 5% (it was read as a fraction, 500%, hiding the probe's 73% overshoot
    warning); 10 is 10%, not refused as beyond 1000%."""
    from vfdsl.check.command import _fraction
    write_probe(tmp_path, PROBE)
    for given in ("5", "5%"):
        proc = run_cli("check", str(tmp_path / "probe.vf"), "--overshoot", given)
        assert "VF102" in proc.stdout and "(limit 5%;" in proc.stdout, proc.stdout
    assert _fraction("5") == _fraction("5%") == pytest.approx(0.05)
    assert _fraction("10") == pytest.approx(0.1) and _fraction("999") == pytest.approx(9.99)
    for text in ("0", "1000", "-5%", "lots"):
        with pytest.raises(argparse.ArgumentTypeError):
            _fraction(text)
    proc = run_cli("check", str(TASKS_DIR / "paper_b_virtual_rcm.vf"), "--scene", str(tmp_path / "none.yaml"))
    assert proc.returncode == 2 and "scene file not found" in proc.stderr


@pytest.mark.parametrize("change, line, column, message", [
    ((("link(\"tool_tip\")", "link(\"tool_tip\"))"),), 4, 33, "unexpected ')'"),                 # syntax
    ((("stays_at(target)", "stays_at(tagret)"),), 9, 22, "unknown point 'tagret'"),              # a name
    ((("[0, 0, 290]", "[0, 0, 29000]"),), 6, 24, "param 'target' is [0, 0, 29] m: beyond"),       # out of reach
    ((("point = [0, 0, 290]", "number = 1e300"), ("stays_at(target)", "stays_at([0, 0, 290] + target * [1, 0, 0] mm)")),
     9, 1, "at the start, the rows of stays_at(tip) hold 1e+297"),                              # found by check
    ("no task", None, None, "file not found: "),
    ("no scene", None, None, "scene file not found: "),
])
def test_cli_json_reports_a_task_that_does_not_load(tmp_path, capsys, monkeypatch, change, line, column, message):
    """--json always prints a report: one that fails to load (or to be analysed) has the error as its one
    finding, VF000, with its file, line and column, and the exit status stays 2 (the diagnostic still goes to
    stderr)."""
    import functools

    from vfdsl.cli import main

    monkeypatch.setattr(sys.modules["vfdsl.check"], "check", functools.partial(check, backend="interpreted"))
    text = PROBE
    for old, new in change if isinstance(change, tuple) else ():
        text = text.replace(old, new)
    path = write_probe(tmp_path, text)
    args = {"no task": [str(tmp_path / "none.vf")],
            "no scene": [str(path), "--scene", str(tmp_path / "none.yaml")]}.get(change, [str(path)])
    assert main(["check", *args, "--json"]) == 2
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert data["exit_status"] == 2 and data["sound"] is False and data["task"] is None
    assert data["file"] == args[0] and data["counts"] == {"error": 1, "warning": 0, "note": 0}
    [finding] = data["findings"]
    assert finding["code"] == "VF000" and finding["name"] == "input-error" and finding["severity"] == "error"
    assert message in finding["message"] and finding["message"] in err and "Traceback" not in err
    if line is None:
        assert finding["location"] is None
    else:
        assert finding["location"]["file"] == str(path)
        assert (finding["location"]["line"], finding["location"]["column"]) == (line, column)
        assert f"{path}:{line}:{column}: error: " in err
    assert main(["check", *args]) == 2 and capsys.readouterr().out == ""         # no JSON asked, none printed


def test_cli_scene_option_replaces_the_scene(tmp_path):
    probe(tmp_path)
    (tmp_path / "far.yaml").write_text(SCENE.replace("insert: 10", "insert: 20"))     # tip 10 mm below target
    proc = run_cli("check", str(tmp_path / "probe.vf"), "--scene", str(tmp_path / "far.yaml"), "--json")
    assert proc.returncode == 1
    assert "VF301" in {f["code"] for f in json.loads(proc.stdout)["findings"]}


# ------------------------------------------------------------------------------------------ residuals

TILTED = SCENE.replace("rcm_a: 0", "rcm_a: 3")          # the tool axis 3 deg from +z


@pytest.mark.parametrize("direction, angle, cause", [
    ("[0, 0, -1]", 177.0, "opposite direction"),      # the insertion direction given instead of the tool axis
    ("[1, 0, 0]", 90.0, "wrong frame axis"),
])
def test_direction_far_off_at_the_start_is_an_error_with_its_cause(tmp_path, direction, angle, cause):
    text = PROBE.replace(STAYS_AT, f"require tip keeps_direction({direction}) within 1 deg")
    task = probe(tmp_path, text, TILTED)
    [finding] = codes(task)["residual-far"]
    assert finding.severity == Severity.ERROR and finding.span.line == 9 and cause in finding.message
    # independent: the angle between the tool axis (Pinocchio) and the direction
    robot = vfdsl.compile(task, backend="interpreted").assembled.context.robot
    _, R = robot.frame_pose(task.start, "tool_tip")
    d = np.array(json.loads(direction), dtype=float)
    expected = math.acos(np.clip(R[:, 2] @ d, -1, 1))
    assert finding.data["error"] == pytest.approx(expected, abs=1e-9)
    assert math.degrees(expected) == pytest.approx(angle, abs=1e-6)


def test_opposite_direction_is_invisible_to_the_rows(tmp_path):
    """The reason the true angle is measured: at 177 deg the rows see 2 - sin(3 deg), not an angle (the paper's
    sine alone: sin(3 deg), as if 3 deg off)."""
    text = PROBE.replace(STAYS_AT, "require tip keeps_direction([0, 0, -1]) within 1 deg")
    [finding] = codes(probe(tmp_path, text, TILTED))["residual-far"]
    assert finding.data["rows_error"] == pytest.approx(2 - math.sin(math.radians(3)), rel=1e-3)


def test_small_start_error_is_a_warning_and_none_inside(tmp_path):
    text = PROBE.replace(STAYS_AT, "require tip keeps_direction([0, 0, 1]) within 1 deg")
    [finding] = codes(probe(tmp_path, text, TILTED))["residual-outside"]
    assert finding.severity == Severity.WARNING and finding.data["error"] == pytest.approx(math.radians(3))
    found = codes(probe(tmp_path, text))                       # tool axis on +z: inside
    assert "residual-outside" not in found and "residual-far" not in found


def test_point_in_the_wrong_unit(tmp_path):
    text = PROBE.replace("[0, 0, 290]", "[0, 0, 0.29]")          # metres in a mm file
    [finding] = codes(probe(tmp_path, text))["residual-far"]
    assert "wrong unit" in finding.message and finding.data["error"] == pytest.approx(0.29 - 0.29e-3)


def test_cone_axis_reversed(tmp_path):
    text = PROBE.replace(STAYS_AT, "require tip cone([0, 0, -1], 3 deg) within 1 deg")
    [finding] = codes(probe(tmp_path, text, TILTED))["residual-far"]
    assert "opposite direction" in finding.message
    assert finding.data["error"] == pytest.approx(math.radians(174))
    assert "residual-far" not in codes(probe(tmp_path, text.replace("[0, 0, -1]", "[0, 0, 1]"), TILTED))


@pytest.mark.parametrize("gamma_deg", [15.0, 80.0, 89.99])
def test_a_cone_s_bound_is_what_its_sine_rows_admit(tmp_path, gamma_deg):
    """A cone's octagon bounds sin(gamma) - sin(theta), not the angle: the table's worst admitted error is the
    largest |theta - gamma| whose continued sine stays within 1.082 eps (a brute-force scan of theta here). The
    controller's own rows hold at rest (dq = 0, OPTIMAL: nothing brings the tool back) with the tool off the cone
    by the angle whose sine error is 0.98 eps (inside the octagon whatever its orientation: 5.6 mrad at 80 deg,
    where the table said 1.08 mrad), and are violated 5 % beyond the bound."""
    from scipy.spatial.transform import Rotation

    from vfdsl.check.polytope import bounds_table
    from vfdsl.kinematics.robot import Robot
    gamma, eps, rho = math.radians(gamma_deg), 1e-3, 1 / math.cos(math.pi / 8)
    theta = np.linspace(0, math.pi, 4_000_001)
    sine = np.where(theta <= math.pi / 2, np.sin(theta), 2 - np.sin(theta))
    def scan(e):
        return np.max(np.abs(theta - gamma)[np.abs(sine - math.sin(gamma)) <= e])
    scanned = scan(rho * eps)
    robot = Robot.load("panda7")
    q0 = np.radians([0, -45, 0, -135, 0, 90, 45])
    l_t = robot.frame_pose(q0, "tool_tip")[1][:, 2]
    k = np.cross(l_t, [1.0, 0, 0])
    k /= np.linalg.norm(k)

    def task_with(delta):
        """The cone's axis at gamma + delta from the tool axis at the start (the tool delta outside the cone)."""
        a = [float(x) for x in Rotation.from_rotvec((gamma + delta) * k).apply(l_t)]
        (tmp_path / "cone.vf").write_text(
            f"task cone\nunits mm, deg\nrobot arm = urdf \"panda7\"\nframe tip = arm.link(\"tool_tip\")\n"
            f"param axis : direction = [{a[0]!r}, {a[1]!r}, {a[2]!r}]\n"
            f"require tip cone(axis, {gamma_deg} deg) within 1 mrad resolution 8\n")
        (tmp_path / "cone.yaml").write_text("units: mm, deg\nperiod: 10 ms\nstart: [0, -45, 0, -135, 0, 90, 45]\n")
        return vfdsl.load(tmp_path / "cone.vf")

    task = task_with(0.0)
    [bound] = bounds_table(task)
    assert bound.worst == pytest.approx(scanned, abs=1e-6)                 # the scan's step: 7.9e-7 rad
    found = codes(task, samples=0).get("polytope-overshoot", [])
    assert bool(found) == (scanned > 1.1 * eps)
    for delta, holds in ((scan(0.98 * eps), True), (1.05 * scanned, False)):
        ctrl = vfdsl.compile(task_with(delta), backend="interpreted")
        dq = ctrl.step(ctrl.task.start, {})
        assert (ctrl.status == StepStatus.OPTIMAL and np.abs(dq).max() < 1e-12) == holds, (delta, dq)


# ------------------------------------------------------------------------------------------ kinematics

def test_frame_on_the_base_is_an_error(tmp_path):
    text = PROBE.replace('frame tip = shr.link("tool_tip")',
                         'frame tip = shr.link("tool_tip")\nframe fixed = shr.link("base")')
    text += "require fixed stays_at([0, 0, 0]) within 0.05\n"
    [finding] = codes(probe(tmp_path, text))["frame-fixed"]
    assert finding.severity == Severity.ERROR and finding.span.line == 5
    assert "frame-fixed" not in codes(probe(tmp_path))


def test_rotation_of_a_stage_link_is_singular(tmp_path):
    """The z stage only translates: its J_w is zero, so an angle constraint on it cannot be corrected."""
    text = PROBE.replace('frame tip = shr.link("tool_tip")',
                         'frame tip = shr.link("tool_tip")\nframe stage = shr.link("stage_z")')
    text += "require stage keeps_direction([0, 0, 1]) within 1 deg\n"
    task = probe(tmp_path, text)
    [finding] = codes(task)["kinematics-near-singular"]
    assert finding.data["block"] == "w" and finding.data["sigma_min"] == pytest.approx(0, abs=1e-12)
    # independent: Pinocchio's Jacobian of the link has rank 3 (the three stages)
    robot = vfdsl.compile(task, backend="interpreted").assembled.context.robot
    assert np.linalg.matrix_rank(robot.frame_jacobian(task.start, "stage_z")) == finding.data["rank"] == 3
    assert "kinematics-near-singular" not in codes(probe(tmp_path))


def test_start_near_a_joint_limit(tmp_path):
    [finding] = codes(probe(tmp_path, scene=SCENE.replace("x: 0", "x: 59.9")))["start-near-limit"]
    assert finding.data["joint"] == "x" and finding.data["limit"] == pytest.approx(0.06)
    assert "start-near-limit" not in codes(probe(tmp_path))


# ------------------------------------------------------------------------------------------ hands off

def test_centering_moves_the_tool_with_the_hands_off(tmp_path):
    text = PROBE.replace("minimize track(tip, f, gain = 1 mm/s/N)\n", "").replace(
        "minimize damping() weight 1e-6", "minimize centering() weight 1")
    task = probe(tmp_path, text, SCENE.replace("x: 0", "x: 30"))
    [finding] = codes(task)["handsoff-drift"]
    assert finding.severity == Severity.WARNING and "`minimize centering` at probe.vf:7" in finding.message
    # independent: run the loop here and measure the tip with Pinocchio
    ctrl = vfdsl.compile(task, backend="interpreted")
    robot = ctrl.assembled.context.robot
    q = task.start.copy()
    for _ in range(50):
        q = q + ctrl.step(q, {"f": [0, 0, 0]})
    moved = np.linalg.norm(robot.frame_pose(q, "tool_tip")[0] - robot.frame_pose(task.start, "tool_tip")[0])
    assert finding.data["moved"] >= moved > 1e-3


def test_a_tracking_task_stays_still_and_a_distance_term_is_a_note(tmp_path):
    assert "handsoff-drift" not in codes(probe(tmp_path))
    text = PROBE.replace("minimize damping() weight 1e-6", "minimize distance(tip, [0, 2, 290])")
    [finding] = codes(probe(tmp_path, text))["handsoff-drift"]
    assert finding.severity == Severity.NOTE and "distance" in finding.message


# ------------------------------------------------------------------------------------------ sampled states

def test_sampled_states_are_reproducible_and_feasible_on_a_sound_task(tmp_path):
    task = probe(tmp_path)
    first = check(task, backend="interpreted", samples=60, seed=3).figures["sampled"]
    again = check(task, backend="interpreted", samples=60, seed=3).figures["sampled"]
    assert first == again and first["samples"] == 60
    assert first["worst_margin"] >= 0
    # a second solver agrees at the worst state: the controller (DAQP) satisfies every row there
    ctrl = vfdsl.compile(task, backend="interpreted")
    ctrl.step(first["worst_margin_q"], {"f": [0, 0, 0]})
    assert ctrl.status == StepStatus.OPTIMAL and not ctrl.violations()
    # the walk moved the tool: the state differs from the start
    assert np.linalg.norm(np.array(first["worst_conditioning_q"]) - task.start) > 0


def test_sampling_flags_a_reached_state_where_the_rows_conflict(tmp_path):
    """The walk is driven by a controller without the stays_at (the tool moves freely under the random
    force); the full task's rows at the states it reaches conflict: stays_at with joint_speed."""
    from vfdsl.check import sampling
    from vfdsl.check.linearized import Linearization

    task = probe(tmp_path)
    free = task.model_copy(update={"constraints": task.constraints[1:]})
    ctrl = vfdsl.compile(free, backend="interpreted")
    figures: dict = {}
    found = sampling.analyse(ctrl, task, Linearization(task, ctrl.assembled.context), 60, 0, figures)
    [infeasible] = [f for f in found if f.name == "sampled-infeasible"]
    assert infeasible.severity == Severity.ERROR and figures["sampled"]["worst_margin"] < 0
    assert sorted(w.rsplit(":", 1)[1] for w in infeasible.data["conflict"]) == ["11", "9"]
    assert "sampled-infeasible" not in codes(task, samples=60)


def test_sampling_reports_ill_conditioned_states(tmp_path):
    text = PROBE.replace('frame tip = shr.link("tool_tip")',
                         'frame tip = shr.link("tool_tip")\nframe stage = shr.link("stage_z")')
    text += "require stage keeps_direction([0, 0, 1]) within 1 deg\n"
    [finding] = codes(probe(tmp_path, text), samples=20)["sampled-ill-conditioned"]
    assert finding.data["worst_conditioning"] == pytest.approx(0, abs=1e-12)
    assert finding.data["worst_conditioning_where"] == "stage.w" and finding.span.line == 5
    assert "sampled-ill-conditioned" not in codes(probe(tmp_path), samples=20)


# ------------------------------------------------------------------------------------------ hygiene

def test_weights_of_one_level_beyond_the_solvers_resolution_are_warned_of(tmp_path):
    """VF805: weights 1e-9 (track) and 1e9 (a soft target) in level 1 span 1e18, beyond the 1e10 the solver resolves
    in one level (two soft targets 10 mm apart weighted 1e9 and 1e-9 pulled the tip halfway, as if equal). Not for
    paper B's 1e6 (damping at 1e-6 of track), nor for terms the same span apart in different levels."""
    soft = ("require tip stays_at([0, 0, 290]) within 1 um soft weight 1e9\n"
            "require tip stays_at([0, 10, 290]) within 1 um soft weight {light}\n")
    track = "minimize track(tip, f, gain = 1 mm/s/N)"
    far = PROBE.replace(track, track + " weight 1e-9")
    found = codes(probe(tmp_path, far.replace(STAYS_AT, soft.format(light="1e-9"))), samples=0)
    [warning] = found["weights-span"]
    assert warning.severity == Severity.WARNING and warning.code == "VF805"
    assert warning.data == {"level": 1, "light": 1e-9, "heavy": 1e9, "phase": None}
    assert "minimize track" in warning.message and "1e+09" in warning.message and warning.span.line == 7
    assert "priority 2" in warning.suggestion
    assert "weights-span" not in codes(probe(tmp_path), samples=0)
    later = soft.format(light="1e-9 priority 2").replace("weight 1e9\n", "weight 1e9 priority 3\n")
    assert "weights-span" not in codes(probe(tmp_path, PROBE.replace(STAYS_AT, later)), samples=0)


def test_unused_declarations(tmp_path):
    text = PROBE.replace("input f : force", "input f : force\ninput spare : torque\nparam p2 : point = [0, 0, 0]")
    found = codes(probe(tmp_path, text))["unused-declaration"]
    assert {(f.data["kind"], f.data["name"], f.span.line) for f in found} == {("input", "spare", 6),
                                                                            ("param", "p2", 7)}
    assert "unused-declaration" not in codes(probe(tmp_path))


def test_a_looser_bound_on_the_same_point_is_redundant(tmp_path):
    text = PROBE + "require tip within_distance(target, 1 mm) resolution 8x8\n"
    [finding] = codes(probe(tmp_path, text))["redundant-constraint"]
    assert finding.span.line == 12 and "stays_at(tip)" in finding.message
    # a tighter one is not: the 8x8 polytope of 30 um (circumradius 34.8 um) lies inside the 12x12 one of
    # 50 um (inradius 50 um), so it is the stays_at that becomes redundant
    tight = PROBE + "require tip within_distance(target, 0.03 mm) resolution 8x8\n"
    [finding] = codes(probe(tmp_path, tight))["redundant-constraint"]
    assert finding.span.line == 9 and "within_distance(tip)" in finding.message
    assert "redundant-constraint" not in codes(probe(tmp_path))


def test_two_points_farther_apart_than_their_tolerances_contradict(tmp_path):
    text = PROBE + "require tip stays_at([0, 0, 290.2]) within 0.05 resolution 12x12\n"
    [finding] = codes(probe(tmp_path, text))["contradictory-tolerances"]
    assert finding.severity == Severity.ERROR and finding.span.line == 9 and ":12" in finding.data["other"]
    # independent: the two cubes-like polytopes (facet distance 50 um) around points 200 um apart along z
    # miss each other by 200 - 2 x 50 um along the z facets: half of that is the uniform violation
    assert finding.data["miss"] == pytest.approx((0.2e-3 - 2 * 0.05e-3) / 2, rel=1e-6)
    assert "contradictory-tolerances" not in codes(probe(tmp_path, text.replace("290.2", "290.05")))


# ------------------------------------------------------------------------------------------ the examples

@pytest.mark.parametrize("path", sorted(TASKS_DIR.glob("*.vf")), ids=lambda p: p.stem)
def test_every_example_task_is_sound_and_explains_its_warnings(path):
    report = check(vfdsl.load(path), backend="interpreted")
    assert report.exit_status() == 0, report.render_text()
    text = path.read_text()
    for finding in report.findings:
        if finding.severity == Severity.WARNING:
            assert finding.code in text, f"{path.name} does not say why {finding.code} stands"


# ------------------------------------------------------------------------------------------ scene gaps, report

def test_no_start_skips_the_analyses_at_the_start(tmp_path):
    found = codes(probe(tmp_path, scene="units: mm, deg\nperiod: 10 ms\n"))
    assert found["no-start"][0].severity == Severity.WARNING
    assert "sampled-summary" not in found and "no-start" not in codes(probe(tmp_path))


def test_no_period_assumes_10_ms(tmp_path):
    scene = SCENE.replace("period: 10 ms\n", "")
    assert "10 ms" in codes(probe(tmp_path, scene=scene))["no-period"][0].message
    assert "no-period" not in codes(probe(tmp_path))


def test_sampled_summary_only_when_sampling(tmp_path):
    task = probe(tmp_path)
    [summary] = codes(task)["sampled-summary"]
    assert summary.severity == Severity.NOTE and summary.data["samples"] == 20
    assert "sampled-summary" not in codes(task, samples=0)


def test_json_report_has_the_documented_fields(tmp_path):
    data = check(probe(tmp_path), backend="interpreted", samples=10).to_json()
    assert set(data) == {"schema", "task", "file", "sound", "exit_status", "counts", "findings", "bounds", "figures"}
    assert set(data["counts"]) == {"error", "warning", "note"}
    for finding in data["findings"]:
        assert set(finding) == {"code", "name", "severity", "message", "suggestion", "subject", "location", "data",
                                "notes"}
        assert CODES[finding["name"]] == finding["code"]
    assert set(data["bounds"][0]) == {"subject", "where", "kind", "stated", "resolution", "facets", "worst"}
    json.dumps(data, allow_nan=False)                      # no inf or NaN
    documented = (Path(__file__).resolve().parent.parent / "docs" / "check.md").read_text()
    assert all(f"| {code} | {name} |" in documented for name, code in CODES.items())


def test_start_outside_the_limits_is_an_error(tmp_path):
    task = probe(tmp_path)
    outside = task.model_copy(update={"scene": task.scene.model_copy(update={"start": [0.07, 0, 0, 0, 0, 0, 0.01]})})
    [finding] = codes(outside, samples=0)["start-outside-limits"]
    assert finding.severity == Severity.ERROR and finding.data["joint"] == "x"
    assert "start-outside-limits" not in codes(task)


def test_check_help_teaches():
    proc = run_cli("check", "--help")
    assert proc.returncode == 0
    for text in ("--scene", "--json", "--strict", "--overshoot", "(default: 10%)", "--samples", "exit status",
                 "docs/check.md"):
        assert text in proc.stdout


def test_the_conflicting_set_is_irreducible(tmp_path):
    """Remove any one member of the subset and the rest hold: the LP's motion satisfies every row and
    bound (checked here with numpy); with all of them the margin is negative."""
    from vfdsl.check.feasibility import irreducible_infeasible_subset
    from vfdsl.check.linearized import Linearization
    from vfdsl.check.lp import LinearSystem

    far = PROBE.replace("[0, 0, 290]", "[0, 0, 280]") + "require tip keeps_direction([0, 0, 1]) within 1 deg\n"
    task = probe(tmp_path, far)
    ctrl = vfdsl.compile(task, backend="interpreted")
    rows = Linearization(task, ctrl.assembled.context).rows(task.start)
    conflict = irreducible_infeasible_subset(rows, ctrl.nq)
    assert [r.constraint.primitive for r in conflict] == ["stays_at", "joint_speed"]
    assert LinearSystem.from_rows(conflict, ctrl.nq).margin()[0] < 0
    for member in conflict:
        system = LinearSystem.from_rows([r for r in conflict if r is not member], ctrl.nq)
        t, dq = system.margin()
        assert t >= 0
        Adq = system.A @ dq
        assert np.all(Adq >= system.lb - 1e-12) and np.all(Adq <= system.ub + 1e-12)
        assert np.all(dq >= system.lo - 1e-12) and np.all(dq <= system.hi + 1e-12)
