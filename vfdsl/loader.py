"""``vfdsl.load(path)``: a ``.vf`` task file (with its libraries and scene) -> the checked IR."""

from __future__ import annotations

from pathlib import Path

from vfdsl.files import path_value
from vfdsl.ir.model import Task
from vfdsl.passes.imports import load_program
from vfdsl.passes.resolve import file_units, resolve


def load(path: str | Path) -> Task:
    """Parse, import, expand and check a task. Raises :class:`vfdsl.VfError` on any mistake in the files."""
    path = path_value(path, "load", ".vf task file", "vfdsl.load('tasks/paper_b_virtual_rcm.vf')")
    main, libraries = load_program(path)
    return resolve(main.module, path, [(lib.module, file_units(lib.module)) for lib in libraries],
                   [str(lib.path) for lib in libraries])
