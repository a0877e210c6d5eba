"""``vfdsl.load(path)``: a ``.vf`` task file (with its libraries and scene) -> the checked IR."""

from __future__ import annotations

import os
from pathlib import Path

from vfdsl.errors import VfError
from vfdsl.ir.model import Task
from vfdsl.passes.imports import load_program
from vfdsl.passes.resolve import file_units, resolve


def load(path: str | Path) -> Task:
    """Parse, import, expand and check a task. Raises :class:`vfdsl.VfError` on any mistake in the files."""
    if not isinstance(path, (str, os.PathLike)):
        raise VfError(f"load() takes the path of a .vf task file, got a {type(path).__name__}",
                      hint="e.g. vfdsl.load('tasks/paper_b_virtual_rcm.vf')")
    path = Path(path)
    main, libraries = load_program(path)
    return resolve(main.module, path, [(lib.module, file_units(lib.module)) for lib in libraries],
                   [str(lib.path) for lib in libraries])
