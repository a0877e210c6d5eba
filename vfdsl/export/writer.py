"""``vfdsl export``: a task's controller as a folder that builds with a C compiler and make (or CMake) alone.

    DIR/
        vf_<task>.h  vf_<task>.hpp  vf_<task>.c     the API (templates/api.*) and the task's tables (tables.py)
        generated/<prefix>.c  .h                    the generated tick, as build.py writes it
        generated/checked_step.h                    the checks and the evaluation (vfdsl/codegen, shared with Python)
        generated/procedure_tick.h  phase_machine.h a procedure's machine (vfdsl/codegen, shared with Python)
        generated/teleop_readout.h                  a teleoperated task's haptic readout (vfdsl/codegen)
        generated/vfmesh_*.c                        the proximity query of each mesh the task uses (vfdsl/mesh)
        generated/lexls.c  lexls.h                  the exact solve of priority levels (vfdsl/codegen/lexls.c)
        daqp/LICENSE  daqp/include/daqp/  daqp/src/ DAQP's C sources (vfdsl/codegen/daqp_sources.py)
        Makefile  CMakeLists.txt  example.c  replay.c  README.md

Everything comes from the files of the task's :class:`~vfdsl.codegen.build.BuiltLibrary` (generated C and
header, metadata) and from DAQP's sources; templates are filled by ``@NAME@`` replacement. Nothing written
depends on the time, the machine, the build cache or how the task's path was given (:func:`portable`), so
exporting an unchanged task again writes the same bytes. Files the export does not write are left alone; a file
it writes is replaced (a new file renamed over it), never written through: a link, or a path under a link, in
the folder is refused before anything is written, and so is a file that is one of the task's own sources.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path, PurePath

import vfdsl
from vfdsl.codegen.build import CHECKED_STEP, LEXLS_HEADER, LEXLS_SOURCE, TELEOP_READOUT, BuiltLibrary
from vfdsl.codegen.procedure_code import PROCEDURE_TICK
from vfdsl.errors import VfError
from vfdsl.export.tables import comment_text, task_tables
from vfdsl.files import check_outputs
from vfdsl.ir import model as ir

TEMPLATES = Path(__file__).parent / "templates"
_PLACEHOLDER = re.compile(r"@([A-Z_]+)@")


@dataclass(frozen=True)
class Export:
    """An exported folder: ``api`` is the C name of the API (``vf_<task>``), ``files`` what was written."""

    directory: Path
    api: str
    files: tuple[Path, ...]


def api_name(task_name: str) -> str:
    """The C prefix of a task's API: ``vf_`` and the task name with every non-identifier character as ``_``."""
    return "vf_" + re.sub(r"[^A-Za-z0-9_]", "_", task_name)


_CPP_TAKEN = frozenset("""
    alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t char16_t char32_t class
    compl concept const consteval constexpr constinit const_cast continue co_await co_return co_yield decltype
    default delete do double dynamic_cast else enum explicit export extern false float for friend goto if inline
    int long mutable namespace new noexcept not not_eq nullptr operator or or_eq private protected public register
    reinterpret_cast requires return short signed sizeof static static_assert static_cast struct switch template
    this thread_local throw true try typedef typeid typename union unsigned using virtual void volatile wchar_t
    while xor xor_eq final override import module
    NULL EOF errno assert offsetof stdin stdout stderr setjmp va_arg va_start va_end va_copy
    numbers num_joints input_length param_length joints_in joints_out inputs_in params_in step set_param set_params
    violations error_message get ctrl_
""".split())
"""Names the C++ owner's class cannot take: C++ keywords (and contextual ones), standard macros a C++ header
may define, and the names inside ``vfdsl::`` (the class's members and the argument type ``numbers``)."""


def cpp_class_name(task_name: str) -> str:
    """The C++ owner's class in ``vfdsl::``: the API's name without ``vf_``, with ``_`` appended when it is taken
    (:data:`_CPP_TAKEN`, e.g. a task named ``class`` or ``step``) or starts with a digit."""
    name = api_name(task_name)[3:]
    return name + "_" if name in _CPP_TAKEN or name[:1].isdigit() else name


def portable(task: ir.Task) -> ir.Task:
    """``task`` with its source paths (the task file, imports, scene, every span) relative to the task file's
    folder, so that what is exported (labels, the generated tick's name, which hashes the IR) does not depend on
    the current directory or on the path being given absolute or relative. A mesh's or URDF's absolute path
    stays: it names the file itself, not how the task was given."""
    if not task.file:
        return task
    home = Path(task.file).resolve().parent
    sources = {task.file, *task.imports, *([task.scene.file] if task.scene and task.scene.file else [])}
    moved = {path: PurePath(os.path.relpath(Path(path).resolve(), home)).as_posix() for path in sources}

    def walk(node):
        if isinstance(node, dict):
            return {key: moved.get(value, value) if key == "file" and isinstance(value, str) else
                    [moved.get(path, path) for path in value] if key == "imports" else walk(value)
                    for key, value in node.items()}
        return [walk(value) for value in node] if isinstance(node, list) else node

    return ir.Task.model_validate(walk(task.model_dump(mode="json")))


def write_export(library: BuiltLibrary, daqp_root: Path, directory: Path,
                 sources: list[tuple[str, str | None]] = ()) -> Export:
    """Write the folder for the generated ``library`` into ``directory`` (created if missing), with DAQP's sources
    from ``daqp_root`` (``LICENSE``, ``include/daqp/*.h``, ``src/*.c``); nothing is written when a file it would
    replace is one of the task's ``sources`` (:func:`vfdsl.files.task_sources`)."""
    meta = json.loads(library.meta_path.read_text())
    api, tick = api_name(meta["task"]), meta["prefix"]
    daqp_sources = sorted((daqp_root / "src").glob("*.c"))
    daqp_headers = sorted((daqp_root / "include" / "daqp").glob("*.h"))
    if not daqp_sources or not (daqp_root / "LICENSE").is_file():
        raise VfError(f"{daqp_root} does not hold DAQP's C sources and LICENSE")
    extra = meta.get("extra_sources", [])
    values = _values(meta, api, tick, [f"daqp/src/{p.name}" for p in daqp_sources], daqp_root.name)
    values["EXTRA_SOURCES"] = " ".join(f"generated/{name}" for name in extra)
    files: dict[str, bytes] = {
        f"{api}.h": _fill("api.h", values), f"{api}.hpp": _fill("api.hpp", values),
        f"{api}.c": _fill("api.c", values), "Makefile": _fill("Makefile", values),
        "CMakeLists.txt": _fill("CMakeLists.txt", values), "example.c": _fill("example.c", values),
        "replay.c": _fill("replay.c", values), "README.md": _fill("README.md", values),
        f"generated/{tick}.c": library.c_path.read_bytes(), f"generated/{tick}.h": library.h_path.read_bytes(),
        "generated/checked_step.h": CHECKED_STEP.read_bytes(),
        "generated/lexls.c": LEXLS_SOURCE.read_bytes(), "generated/lexls.h": LEXLS_HEADER.read_bytes(),
        **{f"generated/{name}": (library.c_path.parent / name).read_bytes() for name in extra},
        **({f"generated/{path.name}": path.read_bytes() for path in PROCEDURE_TICK} if "procedure" in meta else {}),
        **({"generated/teleop_readout.h": TELEOP_READOUT.read_bytes()} if "teleop" in meta else {}),
        "daqp/LICENSE": (daqp_root / "LICENSE").read_bytes(),
        **{f"daqp/include/daqp/{p.name}": p.read_bytes() for p in daqp_headers},
        **{f"daqp/src/{p.name}": p.read_bytes() for p in daqp_sources},
    }
    directory = Path(directory)
    for name in files:
        _refuse_links(directory, name)
        check_outputs({f"-o {directory}: the export's file": directory / name}, sources,
                      hint="export into another folder with -o")
    written = []
    try:
        for name, data in files.items():
            path = directory / name
            path.parent.mkdir(parents=True, exist_ok=True)
            _replace(path, data)
            written.append(path)
    except OSError as exc:
        raise VfError(f"cannot write the export into {directory}: {exc.strerror or exc} ({exc.filename or directory})",
                      hint="choose a writable directory with -o") from None
    return Export(directory, api, tuple(written))


def _refuse_links(directory: Path, name: str) -> None:
    """VfError when writing ``directory/name`` would go through a link, or replace what is not a regular file
    (a folder, a FIFO, a device): the export writes regular files inside ``directory`` only."""
    path = directory
    for part in PurePath(name).parts:
        path = path / part
        if path.is_symlink():
            raise VfError(f"the export will not write through the link {path} (-> {os.readlink(path)}): it writes "
                          f"regular files inside {directory} only, and nothing was written",
                          hint=f"remove the link {path}, or export into an empty folder with -o")
    if path.exists() and not path.is_file():
        raise VfError(f"the export cannot replace {path}: it is not a regular file, and nothing was written",
                      hint=f"move {path} away, or export into an empty folder with -o")


def _replace(path: Path, data: bytes) -> None:
    """``path`` = ``data``, written to a new file renamed over ``path``: a link or a hard link there is replaced,
    never written through."""
    temporary = path.with_name(f".{path.name}.vfdsl-export")
    temporary.unlink(missing_ok=True)
    try:
        descriptor = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
        with os.fdopen(descriptor, "wb") as out:
            out.write(data)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def prepare_directory(directory: Path) -> Path:
    """``directory`` when the export can be written there (checked before anything is generated): a writable
    directory, or a missing one whose nearest existing folder is writable; VfError otherwise. A missing one is
    created by :func:`write_export`, after the build: an export that fails before (no C compiler, a build cache
    that is a file) leaves no empty folder behind."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise VfError(f"the export directory {directory} is not a directory", hint="choose a folder with -o")
    existing = directory
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise VfError(f"cannot create the export directory {directory}: {existing} is not a directory",
                      hint="choose a writable folder with -o")
    if not os.access(existing, os.W_OK | os.X_OK):
        what = "the export directory" if existing == directory else f"the export directory {directory}: its folder"
        raise VfError(f"{what} {existing} is not writable", hint="choose a writable folder with -o")
    return directory


def _fill(template: str, values: dict[str, str]) -> bytes:
    """Template ``template`` with every ``@NAME@`` replaced by ``values[NAME]`` (a missing name is a bug)."""
    text = (TEMPLATES / template).read_text()
    return _PLACEHOLDER.sub(lambda m: values[m.group(1)], text).encode()


def _values(meta: dict, api: str, tick: str, daqp_sources: list[str], daqp_version: str) -> dict[str, str]:
    inputs, params = meta["input_layout"], meta["param_layout"]
    period = meta["period"]
    return {
        "API": api, "TICK": tick, "TASK": meta["task"], "CLASS": cpp_class_name(meta["task"]), "MACRO": api.upper(),
        "GUARD": api.upper() + "_H", "SOURCE": comment_text(meta["file"]), "VERSION": vfdsl.__version__,
        "MAX": str(meta["max_slots"]),
        "MIN_PERIOD": f"{meta['min_period']:g}", "MAX_PERIOD": f"{meta['max_period']:g}", "TABLES": task_tables(meta),
        "NQ": str(_length(meta["inputs"], "q")), "NU": str(_length(meta["inputs"], "u")),
        "NP": str(_length(meta["inputs"], "p")), "NINPUTS": str(len(inputs)), "NPARAMS": str(len(params)),
        "N": str(_length(meta["outputs"], "x")),     # the QP's variables (dq and slacks): lexls.c is compiled for them
        "DAQP_SOURCES": " \\\n  ".join(daqp_sources), "DAQP_SOURCES_CMAKE": "\n  ".join(daqp_sources),
        "DAQP_VERSION": daqp_version,
        "JOINTS": ", ".join(f"{n} ({u})" for n, u in zip(meta["joints"], meta["joint_units"])),
        "INPUTS": ", ".join(f"`{i['name']}` ({i['type']}, {i['size']} numbers, {i['unit']})" for i in inputs) or "none",
        "PARAMS": ", ".join(f"`{p['name']}` ({p['type']}, {p['size']} numbers, {p['unit']})" for p in params) or "none",
        "INPUTS_ARGUMENT": f"const double inputs[{api.upper()}_INPUT_LENGTH]" if inputs else "const double* inputs",
        "PARAMS_ARGUMENT": f"const double values[{api.upper()}_PARAM_LENGTH]" if params else "const double* values",
        "ROWS": str(len(meta["rows"])), "PERIOD": f"{period:g} s" if period else "none (pass dt)",
    }


def _length(buffers: list[dict], name: str) -> int:
    """The length of the step's buffer ``name`` (:mod:`vfdsl.codegen.tick_buffers`) among the metadata's ``inputs``
    or ``outputs`` (the compiled step's arguments and results)."""
    return next(b["shape"][0] for b in buffers if b["name"] == name)
