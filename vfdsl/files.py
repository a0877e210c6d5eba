"""Reading the user's files (tasks, libraries, scenes, URDFs and their sidecars) within the limits, and checking
that an output file can be written before the work that makes it.

A file must be a regular file (not a directory, FIFO or device: those could block or never end) of at most
:data:`~vfdsl.limits.FILE_BYTES`, in UTF-8 (a leading byte-order mark is dropped); the check is
made on the opened descriptor, so the file cannot be swapped between the check and the read. YAML is composed by a loader that refuses nesting deeper
than :data:`~vfdsl.limits.YAML_DEPTH` before Python's own recursion limit could be reached.
"""

from __future__ import annotations

import argparse
import os
import stat
from pathlib import Path

import yaml

from vfdsl.errors import Span, VfError, a_or_an
from vfdsl import limits


def open_file(path: Path, what: str, pos: Span | None = None, hint: str | None = None,
              limit: int = limits.FILE_BYTES) -> int:
    """A descriptor, open for reading, of the regular file of at most ``limit`` bytes at ``path``; VfError at
    ``pos`` when there is none. Opened without blocking, so a FIFO fails here instead of waiting for a writer."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise VfError(f"{what} not found: {path}", pos, hint=hint) from None
    except (OSError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise VfError(f"cannot read {what} {path}: {reason.lower()}", pos) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise VfError(f"cannot read {what} {path}: not a regular file", pos,
                          hint="name a file (not a directory, a pipe or a device)")
        if info.st_size > limit:
            raise _too_large(what, path, limit, pos)
    except BaseException as exc:
        os.close(fd)
        if isinstance(exc, OSError):
            raise VfError(f"cannot read {what} {path}: {(exc.strerror or str(exc)).lower()}", pos) from None
        raise
    return fd


def _too_large(what: str, path: Path, limit: int, pos: Span | None) -> VfError:
    return limits.exceeded(f"{what} {path} is too large", limit, pos, hint="the limit is in bytes")


def read_text(path: Path, what: str, pos: Span | None = None, hint: str | None = None) -> str:
    """The text of the ``what`` (e.g. 'scene file') at ``path``; VfError at ``pos`` when it cannot be read."""
    fd = open_file(path, what, pos, hint)
    try:
        data = os.read(fd, limits.FILE_BYTES + 1)      # a file whose size fstat does not know (/proc) is bounded here
    except OSError as exc:
        raise VfError(f"cannot read {what} {path}: {(exc.strerror or str(exc)).lower()}", pos) from None
    finally:
        os.close(fd)
    if len(data) > limits.FILE_BYTES:
        raise _too_large(what, path, limits.FILE_BYTES, pos)
    try:
        return data.decode("utf-8-sig")          # a leading byte-order mark (some Windows editors) is not text
    except UnicodeDecodeError as exc:
        raise VfError(f"{what} {path} is not UTF-8 text (byte {exc.start})", pos) from None


def path_argument(text: str) -> str:
    """The argparse type of a command's file and folder options: an empty path names nothing (it used to be taken
    as "not given", or as the current directory: `export -o ""` replaced the README.md and Makefile there)."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path names no file or folder")
    return text


def path_value(value, caller: str, what: str, example: str) -> Path:
    """``value`` as a Path when it is one (a str or os.PathLike, not empty), else VfError: the path of ``what`` that
    the Python API's ``caller`` takes, checked as :func:`path_argument` checks the command line's (a number or None
    raised TypeError from deep inside; an empty path was taken as the current directory, or as not given)."""
    try:
        text = os.fspath(value) if isinstance(value, (str, os.PathLike)) else None
    except TypeError:
        text = None
    if not isinstance(text, str):
        raise VfError(f"{caller}() takes the path of {a_or_an(what)}, got {a_or_an(type(value).__name__)}",
                      hint=f"e.g. {example}")
    if not text:
        raise VfError(f"{caller}(): an empty path names no {what}", hint=f"e.g. {example}")
    return Path(text)


def check_writable(name: str | Path) -> None:
    """Refuse an output file before the work that makes it rather than after: its directory must exist, it
    must not be a directory, and it must open for writing, without waiting (a FIFO without a reader is
    refused); a file this creates is removed again."""
    path = Path(name)
    try:
        parent = path.resolve().parent
        if not parent.is_dir():
            raise VfError(f"cannot write {name}: {parent} is not a directory" if parent.exists()
                          else f"cannot write {name}: no directory {parent}")
        if path.is_dir():
            raise VfError(f"cannot write {name}: it is a directory")
        existed = path.exists()
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NONBLOCK, 0o666))   # a FIFO: no wait
    except (OSError, ValueError) as exc:          # a name too long, not writable, with a NUL byte, ...
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise VfError(f"cannot write {name}: {reason}") from None
    if not existed:
        path.unlink(missing_ok=True)


def check_outputs(outputs: dict[str, str | Path | None], inputs: list[tuple[str, str | Path | None]],
                  hint: str = "write the output to another file") -> None:
    """Refuse, before any work, an output file that would destroy a file the command reads or another output:
    ``outputs`` maps each output option (``--json``) to its path (None: not given), ``inputs`` lists the files read
    as (what it is, path). The same file through a link, a hard link or another spelling of its path counts."""
    given = [(option, path) for option, path in outputs.items() if path]
    for k, (option, path) in enumerate(given):
        for what, source in inputs:
            if source and _same_file(path, source):
                raise VfError(f"{option} {path} is {what}: writing the output there would destroy it", hint=hint)
        for other, earlier in given[:k]:
            if _same_file(path, earlier):
                raise VfError(f"{other} {earlier} and {option} {path} name the same file: one output would replace "
                              "the other", hint="give each output its own file")


def task_sources(task) -> list[tuple[str, str | None]]:
    """The source files of a loaded task, as :func:`check_outputs` takes them: the task file, its scene file, the
    files it imports, its robot's URDF file (a shipped robot is no file of the user's) and its meshes' files."""
    return [("the task file", task.file), ("the task's scene file", task.scene.file),
            *(("a file the task imports", path) for path in task.imports),
            *((f"the URDF file of robot {robot.name}", robot.urdf) for robot in task.robots
              if Path(robot.urdf).is_absolute()),
            *((f"the mesh file of param {param.name}", param.value.file) for param in task.params
              if getattr(param.value, "kind", None) == "mesh")]


def _same_file(a: str | Path, b: str | Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):                # one of them does not exist (yet)
        return os.path.realpath(a) == os.path.realpath(b)


class BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing lists and mappings nested deeper than ``limits.YAML_DEPTH``."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > limits.YAML_DEPTH:
                raise yaml.composer.ComposerError(None, None, f"nested more than {limits.YAML_DEPTH} levels deep",
                                                  self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1
