"""Imports: read a task file and every library it imports (transitively), detecting import cycles.

``import "lib/fixtures.vf"`` is resolved relative to the importing file. An imported file must be a ``.vf``
file that starts with ``library NAME`` and may hold only ``units``, ``import`` and ``fixture`` statements. A
file reached twice (a diamond) is read once; a file that imports itself, directly or not, is an error at the
import that closes the cycle. Imports nest at most ``limits.IMPORT_DEPTH`` deep, and a program reads at most
``limits.IMPORTED_FILES`` files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vfdsl.errors import VfError
from vfdsl import limits
from vfdsl.files import read_text
from vfdsl.syntax import ast
from vfdsl.syntax.parser import parse_module

_LIBRARY_STATEMENTS = (ast.UnitsStmt, ast.ImportStmt, ast.FixtureDef)


@dataclass(frozen=True)
class SourceFile:
    path: Path
    module: ast.Module


def read_source(path: Path, pos=None) -> SourceFile:
    return SourceFile(path, parse_module(read_text(path, "file", pos), str(path)))


def load_program(entry: Path) -> tuple[SourceFile, list[SourceFile]]:
    """The entry task file and its libraries, each library after the ones it imports."""
    main = read_source(entry)
    if main.module.header != "task":
        raise VfError(f"{entry.name} is a library; load a task file (one that starts with `task NAME`)",
                      main.module.name.span, code="E601")
    libraries: dict[Path, SourceFile] = {}
    _visit(main, [main.path.resolve()], libraries)
    return main, list(libraries.values())


def _visit(source: SourceFile, stack: list[Path], done: dict[Path, SourceFile]) -> None:
    for stmt in source.module.statements:
        if not isinstance(stmt, ast.ImportStmt):
            continue
        if not stmt.path.endswith(".vf"):
            raise VfError(f"'{stmt.path}' is not a .vf file", stmt.span,
                          hint="only libraries of fixtures (.vf files that start with `library NAME`) can be imported",
                          code="E601")
        if len(stack) > limits.IMPORT_DEPTH:
            raise limits.exceeded("imports nested too deeply", limits.IMPORT_DEPTH, stmt.span, code="E701")
        path = source.path.parent / stmt.path
        try:
            target = path.resolve()
        except (OSError, ValueError, RuntimeError) as exc:
            raise VfError(f"cannot read file {path}: {exc}", stmt.span, code="E601") from None
        if target in stack:
            cycle = " -> ".join(p.name for p in stack[stack.index(target):] + [target])
            raise VfError(f"import cycle: {cycle}", stmt.span, hint="a library cannot import itself, "
                          "directly or through other libraries", code="E601")
        if target in done:
            continue
        if len(done) >= limits.IMPORTED_FILES:
            raise limits.exceeded("too many imported files", limits.IMPORTED_FILES, stmt.span, code="E701")
        library = read_source(path, stmt.span)
        if library.module.header != "library":
            raise VfError(f"'{stmt.path}' is a task, not a library", stmt.span,
                          hint="only files that start with `library NAME` can be imported", code="E601")
        for inner in library.module.statements:
            if not isinstance(inner, _LIBRARY_STATEMENTS):
                raise VfError(f"a library holds only fixtures, imports and units; this {inner.kind} statement "
                              "belongs in a task", inner.span, code="E601")
        _visit(library, stack + [target], done)
        done[target] = library
