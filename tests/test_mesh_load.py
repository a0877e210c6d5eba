"""A mesh param's file: its size is limited (triangles and bytes) and any path that is not a readable regular file is
an error at the file name (the task's string or the scene's value), never a traceback."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl import limits
from vfdsl.cli import main as cli_main
from vfdsl.errors import VfError
from vfdsl.mesh import load

LINE = 'param ball : mesh(unit = 1 mm) = "{}"'
COLUMN = LINE.index('"') + 1


def strip_stl(path: Path, triangles: int) -> Path:
    """A binary STL of ``triangles`` triangles: a strip of right triangles 0.1 mm wide, 10 mm long (file units:
    mm), written with NumPy (50 bytes a triangle)."""
    k = np.arange(triangles)
    x0, x1 = 10.0 * k / triangles, 10.0 * (k + 1) / triangles
    lower = k % 2 == 0                                   # alternate triangles of the quads between x0 and x1
    corners = np.zeros((triangles, 3, 3), dtype=np.float32)
    corners[:, 0, 0], corners[:, 1, 0], corners[:, 2, 0] = x0, x1, np.where(lower, x1, x0)
    corners[:, 2, 1] = 0.1
    record = np.zeros(triangles, dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
    record["normal"][:, 2] = 1.0
    record["corners"] = corners
    with open(path, "wb") as out:
        out.write(b"\0" * 80 + np.uint32(triangles).tobytes() + record.tobytes())
    return path


def task(folder: Path, file: str, scene: str | None = None) -> Path:
    path = folder / "t.vf"
    path.write_text('task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
                    f"{LINE.format(file)}\nrequire tip outside_mesh(ball, 1 mm)\n"
                    + (f'scene "{scene}"\n' if scene else ""))
    return path


def load_error(path: Path) -> VfError:
    with pytest.raises(VfError) as err:
        vfdsl.load(path)
    return err.value


def test_a_mesh_of_more_triangles_than_the_limit_is_refused_at_its_line(tmp_path):
    """The limit itself (not a lowered one): one triangle more is refused at the file name, before the vertices
    are merged or any table is built; the hint says how to get below it."""
    strip_stl(tmp_path / "big.stl", limits.MESH_TRIANGLES + 1)
    err = load_error(task(tmp_path, "big.stl"))
    assert err.message == f"big.stl has {limits.MESH_TRIANGLES + 1:,} triangles: the limit is {limits.MESH_TRIANGLES:,}"
    assert (err.pos.line, err.pos.column) == (5, COLUMN)
    assert "decimate" in err.hint and f"{limits.MESH_TRIANGLES:,}" in err.hint


def test_the_triangle_limit_is_inclusive_and_counts_the_file(tmp_path, monkeypatch):
    """At the limit a mesh loads; above it, it is refused however its triangles are written (ASCII STL, OBJ)."""
    import trimesh

    monkeypatch.setattr(limits, "MESH_TRIANGLES", 200)
    task(tmp_path, "ok.stl")
    strip_stl(tmp_path / "ok.stl", 200)
    assert vfdsl.load(tmp_path / "t.vf").param("ball").value.file == str((tmp_path / "ok.stl").resolve())
    mesh = trimesh.load(strip_stl(tmp_path / "strip.stl", 201), process=False)
    for name, kind in (("big.stl", "stl_ascii"), ("big.obj", "obj")):
        mesh.export(tmp_path / name, file_type=kind)
        err = load_error(task(tmp_path, name))
        assert err.message == f"{name} has 201 triangles: the limit is 200" and err.pos.line == 5


def test_a_file_larger_than_any_mesh_within_the_limit_is_refused_unread(tmp_path, monkeypatch):
    """A file of more bytes than MESH_FILE_BYTES is refused from its size: it is never parsed into memory (a
    sparse file of that size holds no triangle at all)."""
    huge = tmp_path / "huge.stl"
    with open(huge, "wb") as out:
        out.truncate(limits.MESH_FILE_BYTES + 1)
    monkeypatch.setattr(load, "_read", lambda *args: pytest.fail("the file was read"))
    err = load_error(task(tmp_path, "huge.stl"))
    assert err.message == (f"huge.stl is {limits.MESH_FILE_BYTES + 1:,} bytes, more than a mesh of "
                           f"{limits.MESH_TRIANGLES:,} triangles takes in any format: the limit is "
                           f"{limits.MESH_FILE_BYTES:,} bytes")
    assert (err.pos.line, err.pos.column) == (5, COLUMN)


def test_the_file_limit_holds_every_format_of_a_mesh_at_the_triangle_limit():
    """MESH_FILE_BYTES allows each triangle more bytes than any format takes, with every number written to full
    precision (ASCII STL, the most verbose, ~290; OBJ and PLY with shared vertices ~30, without ~200): a file
    within the triangle limit is never refused for its size."""
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=3, radius=20.0)
    mesh.vertices -= np.pi                                   # no short numbers, and minus signs
    soup = trimesh.Trimesh(mesh.triangles.reshape(-1, 3), np.arange(3 * len(mesh.faces)).reshape(-1, 3),
                           process=False)                   # no shared vertices: three per triangle
    for shape in (mesh, soup):
        for kind, options in (("stl", {}), ("stl_ascii", {}), ("obj", {}), ("ply", {"encoding": "ascii"})):
            data = shape.export(file_type=kind, **options)
            per_triangle = len(data.encode() if isinstance(data, str) else data) / len(shape.faces)
            assert per_triangle < 0.8 * limits.MESH_FILE_BYTES / limits.MESH_TRIANGLES, (kind, per_triangle)


@pytest.mark.parametrize("make, message", [
    (lambda d: (os.symlink("b.stl", d / "a.stl"), os.symlink("a.stl", d / "b.stl")), "a.stl: a symlink loop"),
    (lambda d: os.symlink("a.stl", d / "a.stl"), "a.stl: a symlink loop"),
    (lambda d: (os.symlink("loop", d / "loop"), os.symlink("loop/x.stl", d / "a.stl")), "a.stl: a symlink loop"),
    (lambda d: os.symlink("missing.stl", d / "a.stl"), "a.stl not found (a symlink to a missing file)"),
    (lambda d: os.mkfifo(d / "a.stl"), "a.stl is not a regular file"),
    (lambda d: os.symlink("/dev/null", d / "a.stl"), "a.stl is not a regular file"),
    (lambda d: (d / "a.stl").mkdir(), "a.stl is a directory, not a mesh file"),
])
def test_a_path_that_is_no_readable_file_is_an_error_at_its_line(tmp_path, make, message):
    make(tmp_path)
    err = load_error(task(tmp_path, "a.stl"))
    assert message in err.message and (err.pos.line, err.pos.column) == (5, COLUMN)


def test_the_format_is_the_named_file_s(tmp_path):
    """A symlink named .stl to a file without a suffix (a content-addressed store) is read as STL; a flat patch
    (zero volume) reads without a warning."""
    import warnings

    strip_stl(tmp_path / "blob", 10)
    os.symlink("blob", tmp_path / "a.stl")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert vfdsl.load(task(tmp_path, "a.stl")).param("ball").value.file == str(tmp_path / "a.stl")
    assert load.read_mesh(tmp_path / "a.stl", 1e-3).volume == 0


def test_a_name_too_long_or_with_a_nul_is_an_error_at_the_scene_value(tmp_path):
    (tmp_path / "ok.stl").write_bytes(b"")
    for value, message in (('"' + "x" * 300 + '.stl"', "File name too long"), ('"a\\0.stl"', "embedded null byte")):
        (tmp_path / "s.yaml").write_text(f"units: mm\nparams:\n  ball: {value}\n")
        err = load_error(task(tmp_path, "ok.stl", scene="s.yaml"))
        assert message in err.message, err.message
        assert Path(err.pos.file).name == "s.yaml" and (err.pos.line, err.pos.column) == (3, 9)


def test_a_symlink_loop_through_the_command_is_a_message(tmp_path, capsys):
    os.symlink("a.stl", tmp_path / "a.stl")
    assert cli_main(["check", str(task(tmp_path, "a.stl"))]) == 2
    err = capsys.readouterr().err
    assert "a symlink loop" in err and f"t.vf:5:{COLUMN}" in err and "Traceback" not in err
