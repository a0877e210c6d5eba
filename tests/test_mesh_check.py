"""`vfdsl check` on mesh fixtures: the mesh's validity, the clearance at the start, unusual extents, and the margin
against one tick's linearization (VF901-VF906)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

import vfdsl
from vfdsl.check import check
from vfdsl.check.report import Severity

SCENE = "units: mm, deg\nperiod: 10 ms\nstart: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 20}\n"


def _probe(folder: Path, mesh: trimesh.Trimesh, primitive="outside_mesh", margin="1 mm", extra="") -> dict:
    """check() of a task whose tip (at (0, 0, 280) mm) keeps ``margin`` from ``mesh``: findings by name."""
    mesh.export(folder / "m.stl")
    (folder / "t.yaml").write_text(SCENE)
    (folder / "t.vf").write_text(
        "task t\nunits mm, deg\nrobot shr = urdf \"shr7\"\nframe tip = shr.link(\"tool_tip\")\ninput f : force\n"
        "param m : mesh = \"m.stl\"\nminimize track(tip, f, gain = 1 mm/s/N)\nminimize damping() weight 1e-6\n"
        f"require tip {primitive}(m, margin = {margin})\n{extra}")
    report = check(vfdsl.load(folder / "t.vf"), samples=0, backend="interpreted")
    found: dict = {}
    for f in report.findings:
        found.setdefault(f.name, []).append(f)
    return found


def _ball(radius=6.0, centre=(12, 0, 280), subdivisions=2) -> trimesh.Trimesh:
    ball = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    ball.apply_translation(centre)
    return ball


def test_clearance_at_start(tmp_path):
    [note] = _probe(tmp_path, _ball())["mesh-start-clearance"]
    assert note.severity == Severity.NOTE and note.data["clearance"] == pytest.approx(0.006, abs=2e-4)
    [warning] = _probe(tmp_path, _ball(centre=(6.5, 0, 280)))["mesh-start-clearance"]
    assert warning.severity == Severity.WARNING and 0 < warning.data["clearance"] < 0.001
    [error] = _probe(tmp_path, _ball(centre=(3, 0, 280)))["mesh-start-clearance"]
    assert error.severity == Severity.ERROR and error.data["clearance"] == pytest.approx(-0.003, abs=2e-4)
    assert error.span.line == 9


def test_inside_mesh_needs_a_closed_mesh(tmp_path):
    ball = _ball(radius=20, centre=(0, 0, 280))
    ball.update_faces(np.arange(len(ball.faces)) != 0)              # a hole
    [error] = _probe(tmp_path, ball, "inside_mesh")["mesh-open"]
    assert error.severity == Severity.ERROR
    [note] = _probe(tmp_path, ball)["mesh-open"]
    assert note.severity == Severity.NOTE


def test_inverted_normals(tmp_path):
    ball = _ball()
    ball.invert()
    [error] = _probe(tmp_path, ball)["mesh-inverted"]
    assert error.severity == Severity.ERROR and "inward" in error.message


def test_degenerate_and_repeated_triangles(tmp_path):
    ball = _ball()
    faces = np.vstack([ball.faces, ball.faces[:3], [[0, 0, 1]]])
    [warning] = _probe(tmp_path, trimesh.Trimesh(ball.vertices, faces, process=False))["mesh-degenerate"]
    assert warning.data == {"degenerate": 1, "duplicate": 3}


def test_unusual_extent(tmp_path):
    [warning] = _probe(tmp_path, _ball(radius=0.6, centre=(12, 0, 280)))["mesh-extent"]
    assert warning.severity == Severity.WARNING and warning.data["extent"] == pytest.approx(0.0012, rel=0.01)


def test_margin_against_one_tick(tmp_path):
    """At the joints' speed limits a tick moves the tip ~1 mm (10 ms): a 0.1 mm margin is below the bound; a hard
    speed limit of 5 mm/s (4x4 polytope: 8.7 mm/s) brings the bound to 0.48 x 0.087 mm = 42 um."""
    [warning] = _probe(tmp_path, _ball(), margin="0.1 mm")["mesh-margin-linearization"]
    assert warning.data["bound"] > 0.0001 and warning.data["step"] > 0.0005
    found = _probe(tmp_path, _ball(), margin="0.1 mm", extra="require tip speed(5 mm/s)\n")
    assert "mesh-margin-linearization" not in found


# A mesh beyond reach gives rows that always hold (0 >= -inf): inactive is not redundant (VF804, never VF802)

@pytest.mark.parametrize("primitive, mesh", [
    ("outside_mesh", _ball(centre=(60, 0, 280))),               # 54 mm from the tip; rows within 1 + 2 mm
    ("inside_mesh", _ball(radius=20, centre=(0, 0, 280))),      # the tip at the centre, 20 mm from the wall
])
def test_a_mesh_beyond_reach_is_inactive_never_redundant(tmp_path, primitive, mesh):
    found = _probe(tmp_path, mesh, primitive, extra="require joint_limits()\n")
    assert "redundant-constraint" not in found
    [note] = found["inactive-constraint"]
    assert note.severity == Severity.NOTE and note.code == "VF804" and note.span.line == 9
    assert note.data == {"states": 1} and "remove" not in note.message + note.suggestion


def test_a_duplicate_mesh_fixture_within_reach_is_still_redundant(tmp_path):
    """2.5 mm from the ball (rows within 1 mm + 2 mm): the second of two equal fixtures adds nothing."""
    found = _probe(tmp_path, _ball(centre=(8.5, 0, 280)), extra="require tip outside_mesh(m, margin = 1 mm)\n")
    [finding] = found["redundant-constraint"]
    assert finding.span.line == 10 and finding.data["acting_states"] == finding.data["states"] == 1
    assert finding.data["implied_by"] == ["t.vf:9"] and "inactive-constraint" not in found


@pytest.mark.parametrize("name, samples, inactive", [("bone_nerve", 20, 2), ("sinus_channel", 0, 1)])
def test_the_example_mesh_tasks_are_never_told_to_remove_a_fixture(name, samples, inactive):
    """bone_nerve: the tool stays more than 2 mm from both meshes at the start and in random motion;
    sinus_channel: at the start it is in the middle of the channel. Both were VF802 ("remove it")."""
    task = vfdsl.load(Path(__file__).resolve().parent.parent / "tasks" / f"{name}.vf")
    names = [f.name for f in check(task, samples=samples, backend="interpreted").findings]
    assert "redundant-constraint" not in names and names.count("inactive-constraint") == inactive


def test_view_draws_the_mesh_in_its_registration():
    """`vfdsl view` draws a mesh fixture as the mesh in the world (moved by its pose param) and the clearance
    capsule around the tool (tests/test_view.py checks the tool's shapes)."""
    from vfdsl.sim.geometry import Scene
    from vfdsl.sim import shapes
    from vfdsl.mesh.load import read_mesh

    task = vfdsl.load(Path(__file__).resolve().parent.parent / "tasks" / "bone_nerve.vf")
    frames = vfdsl.compile(task, backend="interpreted").frames(task.start)
    scene = Scene(task)
    scene.values["patient"] = scene.values["patient"].model_copy(update={"translation": [0.01, 0.0, 0.0]})
    nerve = next(f for f in shapes.build(task, scene, frames) if f.title.startswith("outside_mesh(tip)"))
    mesh = next(s for s in nerve.shapes if s.name == "mesh")
    value = task.param("nerve").value
    assert mesh.role == "forbidden" and not mesh.wireframe
    assert np.allclose(mesh.vertices, read_mesh(value.file, value.unit).vertices + [0.01, 0, 0])
    clearance = next(s for s in nerve.shapes if s.name == "clearance")
    a, b = frames["tip"].position, frames["shaft"].position
    axis = np.clip((clearance.vertices - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    assert np.allclose(np.linalg.norm(clearance.vertices - (a + axis[:, None] * (b - a)), axis=1), 0.003)


def test_simulate_scores_clearance_and_contact():
    """The simulator's metrics of a mesh fixture: max(0, margin - clearance) by brute force, and the share of
    ticks within 0.05 mm of the margin."""
    from vfdsl.sim.geometry import Scene
    from vfdsl.sim.metrics import MetricDef, Poses, errors
    from vfdsl.kinematics.robot import Robot

    task = vfdsl.load(Path(__file__).resolve().parent.parent / "tasks" / "bone_nerve.vf")
    robot = Robot.load(task.robots[0].urdf)
    c = next(c for c in task.constraints if c.frame == "tip" and c.primitive == "outside_mesh")
    # the tool's axis at x = 6 mm (over the nerve's axis), tip 2.5, 3.04 and 10 mm above the nerve's top
    tips = np.array([[0.006, 0, 0.2605 + h] for h in (0.0025, 0.00304, 0.010)])
    poses = Poses({"tip": tips, "shaft": tips + [0, 0, 0.04]}, {})
    error = errors(MetricDef("e", "mm", "length", c), task, robot, Scene(task), poses, None, 0.01)
    contact = errors(MetricDef("k", "%", "contact", c), task, robot, Scene(task), poses, None, 0.01)
    assert error == pytest.approx([0.5, 0.0, 0.0], abs=0.02)     # mm: clearance 2.5 - 1 = 1.5 mm for a 2 mm margin
    assert list(contact) == [100.0, 100.0, 0.0]
