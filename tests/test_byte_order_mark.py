"""Files that start with a UTF-8 byte-order mark (as some Windows editors write them) read as if it were
not there: tasks, libraries, task scenes and simulation scenes; and diagnostics still point at the right
column of their first line."""

from __future__ import annotations

import shutil

import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.errors import VfError
from vfdsl.sim.scene_file import load_settings
from vfdsl.syntax.parser import parse_module

BOM = "\ufeff".encode("utf-8")


def _with_bom(path):
    path.write_bytes(BOM + path.read_bytes())


@pytest.fixture
def b_with_boms(tmp_path):
    """Experiment B with a byte-order mark at the start of its task, its library and both its scenes."""
    for name in ("paper_b_virtual_rcm.vf", "paper_b_virtual_rcm.yaml", "paper_b_virtual_rcm.sim.yaml"):
        shutil.copy(TASKS_DIR / name, tmp_path / name)
    shutil.copytree(TASKS_DIR / "library", tmp_path / "library")
    for path in (tmp_path / "paper_b_virtual_rcm.vf", tmp_path / "paper_b_virtual_rcm.yaml",
                 tmp_path / "paper_b_virtual_rcm.sim.yaml", tmp_path / "library" / "fixtures.vf"):
        _with_bom(path)
        assert path.read_bytes().startswith(BOM)
    return tmp_path / "paper_b_virtual_rcm.vf"


def test_task_library_and_scenes_with_a_bom_load_like_the_originals(b_with_boms):
    original = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    task = vfdsl.load(b_with_boms)
    assert task.name == original.name
    assert task.start.tolist() == original.start.tolist()
    assert [c.primitive for c in task.constraints] == [c.primitive for c in original.constraints]
    settings = load_settings(task, b_with_boms.with_suffix(".sim.yaml"))
    assert settings.period == 0.01 and settings.trials == 5 and settings.hand.input == "tau"


def test_show_accepts_a_task_with_a_bom(b_with_boms, capsys):
    assert main(["show", str(b_with_boms)]) == 0
    assert "paper_b_virtual_rcm" in capsys.readouterr().out


def test_a_diagnostic_on_the_first_line_of_a_bom_file_points_at_the_right_column(tmp_path):
    path = tmp_path / "t.vf"
    path.write_bytes(BOM + b"task t units mm\n")
    with pytest.raises(VfError) as err:
        vfdsl.load(path)
    assert err.value.pos.line == 1
    rendered = err.value.render()
    assert "\ufeff" not in rendered and "not a .vf file" not in rendered


def test_parse_module_of_text_with_a_bom():
    module = parse_module("\ufefftask t\nunits mm\n", "t.vf")
    assert module is not None
