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
