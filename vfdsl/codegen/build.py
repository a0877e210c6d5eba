"""Generate C for a CasADi Function, compile it against DAQP, and cache the shared library.

One cache entry per content digest::

    <cache_dir>/<prefix>-<digest[:16]>/
        <prefix>.c  <prefix>.h   generated source (exported symbol: ``<prefix>``)
        lib<prefix>-<nonce>.so   the library; the nonce makes every build's path unique, because
                                 glibc hands out an already-loaded library of the same path again
        <prefix>.json            caller metadata + sizes, digest, compiler, flags, so_sha256, ...

digest = sha256(generated C and header, compiler flags, compiler ``--version`` line, resolved
target (``-###`` output, which pins ``-march=native`` to this CPU), CasADi and DAQP versions, metadata).

The generated C is compiled against DAQP's own C sources (:mod:`vfdsl.codegen.daqp_sources`: the version of the
installed ``daqp`` package, with priority levels), built once per cache into a static library whose symbols stay
hidden inside each task's library; CasADi's bundled DAQP is not used.

An entry is used only if its metadata parses and names the same digest, every file exists, and
the .so has the recorded sha256 and loads with the exported symbol; anything else (truncated or
foreign .so, missing file, edited metadata) is rebuilt. A build happens in a private temporary
directory inside ``cache_dir`` (same filesystem) and is published with one ``os.replace`` of the
whole directory; two processes racing on one entry both end up with a complete, verified library,
and a library file already mapped by a process is never written to.

Building is three steps: :func:`_generate` (CasADi's C of the step, patched by
:func:`vfdsl.codegen.patch.patch_generated_c` as each conic's :class:`~vfdsl.codegen.solve_plan.SolvePlan` says),
:func:`_compile` (the libraries and their metadata, in the private directory) and :func:`_publish` (the atomic move
into the cache).
"""

from __future__ import annotations

import contextlib
import dataclasses
import ctypes
import datetime
import functools
import hashlib
import importlib.util
import json
import os
import re
import secrets
import shlex
import shutil
import subprocess
import sysconfig
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca

from vfdsl.codegen.daqp_sources import announce, daqp_sources, daqp_version, source_files
from vfdsl.codegen.patch import LEXLS_HEADER, LEXLS_SOURCE, MAX_SLOTS, patch_generated_c
from vfdsl.codegen.solve_plan import plans_of
from vfdsl.codegen import procedure_code
from vfdsl.codegen.procedure_code import PROCEDURE_TICK, PhaseCode
from vfdsl.codegen.tick_buffers import c_call, c_declarations
from vfdsl.errors import VfError

FLAGS = ("-O3", "-march=native", "-ffp-contract=off", "-fPIC", "-pthread", "-fvisibility=hidden", "-fno-math-errno",
         "-Werror=implicit-function-declaration",
         "-DGCC_HASCLASSVISIBILITY")
"""Speed flags. Never ``-ffast-math``: the step's NaN/inf checks must survive optimisation."""
OPTIMIZE = "VFDSL_OPTIMIZE"
"""The environment variable that sets the optimisation of a task's own C (its generated step, the Python
extension and its meshes' query libraries, vfdsl.mesh.external; DAQP's and the certificate's libraries stay at
-O3): O3 (default), O2, O1 or O0. The arithmetic is
IEEE's at every level (-ffp-contract=off, never -ffast-math), so a tick's answer is the same to the bit; O0 builds
about 4x faster and ticks slower (the test suite builds at O0, tests/conftest.py)."""
STEPPER = Path(__file__).parent / "stepper.c"
STEPPER_PARTS = (STEPPER, STEPPER.with_name("stepper_values.h"), STEPPER.with_name("stepper_procedure.h"))
"""The Python extension's source: stepper.c and the parts it includes."""
CHECKED_STEP = Path(__file__).parent / "checked_step.h"
TELEOP_READOUT = Path(__file__).parent / "teleop_readout.h"
"""The checks and the evaluation of a tick in plain C: included by stepper.c and by `vfdsl export`'s library."""

_LEXLS_KEY = hashlib.sha256(LEXLS_SOURCE.read_bytes() + LEXLS_HEADER.read_bytes()).hexdigest()
"""lexls.c is compiled into a static library per number of variables (:func:`lexls_library`), not into each task's C:
its hash names those libraries and enters every task's digest."""
HEADER_CONTRACT = """
/* vfdsl: how to call @PREFIX@ from C (no Python needed).
 *
 *   int slot = @PREFIX@_checkout();      one slot per controller: -1 when all @SLOTS@ are taken
 *   @PREFIX@(arg, res, iw, w, slot);     one tick; @CALL@
 *   @PREFIX@_release(slot);              frees the slot's solver memory
 *
 * - A slot holds the solvers' workspaces and warm start: give each controller (each thread) its own
 *   slot and its own arg/res/iw/w arrays (sizes: @PREFIX@_work). Different slots run in parallel.
 * - One slot used by two threads at once is refused: the second call returns 3 and touches nothing.
 *   A slot that is not checked out returns 2. 0 means the outputs are valid.
 * - The function does not check its inputs: pass finite numbers, q within the joint limits (or near
 *   them), dt > 0, recover = 0 (1 forces the least-violation phase). Whatever they are, x is finite and
 *   inside the joint bounds, or the rest motion with the FALLBACK bit (4) in status.
 * - Params other than the defaults: check them first with @PREFIX@_admissible(arg = {p}, res = {margins},
 *   iw, w, 0) (sizes: @PREFIX@_admissible_work); check i holds iff margins[i] is finite and >= 0 (> 0 where
 *   "strict" in the .json), and the .json lists what each check means. Step only when every check holds.
 * - Inputs: check them each tick with @PREFIX@_input_checks(arg = {u}, res = {margins}, iw, w, 0) (sizes:
 *   @PREFIX@_input_checks_work) after checking that every number of u is finite: margin m holds iff it is
 *   finite and >= 0; it is check m / nu of u[m % nu] (the .json's inputs say each type's checks).
 * - status bits: 0 OPTIMAL, 1 LEAST_VIOLATION, 2 BOUNDS_CLIPPED, 4 FALLBACK, 8 UNCERTIFIED; violation[i] is row i's
 *   excess (the rows are listed in the .json next to this header).
 * - The first call on a slot allocates the DAQP workspaces; later calls allocate nothing.
 */
"""
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
CACHE_OPTIONS = "the build cache (compile -o, export --cache, or $VFDSL_CACHE)"
"""How a user names the build cache, for hints (each command names it its own way)."""


class CompilerUnavailable(VfError):
    """No working C compiler: use the interpreted path, or install one / set ``CC``."""


@dataclass(frozen=True)
class BuiltLibrary:
    so_path: Path                    # the C library (exported symbol: the prefix)
    c_path: Path
    h_path: Path
    meta_path: Path
    digest: str
    module_path: Path | None = None  # the Python extension (stepper.c), None without Python headers
    reused: bool = False             # True when a verified cache entry was used, nothing compiled


@dataclass(frozen=True)
class Compiler:
    command: tuple[str, ...]
    version: str
    target: str


def build_library(fn: ca.Function, prefix: str, cache_dir: Path, metadata: dict,
                  checks: ca.Function, extra_sources: tuple[Path, ...] = (),
                  input_checks: ca.Function | None = None, phases: PhaseCode | None = None,
                  teleop: ca.Function | None = None) -> BuiltLibrary:
    """The cached library of the step ``fn`` (arguments q, u, p, dt, recover), exported as C symbol ``prefix``,
    with ``checks`` (p -> the column of checks of the params, :mod:`vfdsl.compiler.admissible`) exported as
    ``<prefix>_admissible`` and ``input_checks`` (u -> the column of the inputs' checks,
    :func:`vfdsl.runtime.values.input_checks`; None: none beyond finiteness) as ``<prefix>_input_checks``; built
    if needed. ``extra_sources``: C files defining the external functions ``fn`` calls (mesh queries), compiled
    and linked in with the same flags (their text is part of the digest). ``phases``: a procedure's step (which takes
    :data:`~vfdsl.codegen.tick_buffers.PHASE_BUFFERS` after dt) with its machine and functions
    (:class:`~vfdsl.codegen.procedure_code.PhaseCode`). ``teleop``: a teleoperated task's readout
    (:mod:`vfdsl.objectives.haptics`), exported as ``<prefix>_teleop_readout`` (codegen/teleop_readout.h calls it)."""
    if not _IDENTIFIER.fullmatch(prefix):
        raise ValueError(f"prefix {prefix!r} is not a C identifier")
    cache_dir = Path(cache_dir)
    if cache_dir.exists() and not cache_dir.is_dir():
        raise VfError(f"the build directory {cache_dir} is not a directory",
                      hint=f"point {CACHE_OPTIONS} at a directory (it is created if missing)")
    compiler = find_compiler()
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
        work_dir = tempfile.TemporaryDirectory(dir=cache_dir, prefix=f".build-{prefix}-")
    except OSError as exc:   # read-only or full: a valid entry is still used, else build elsewhere
        work_dir, fallback = tempfile.TemporaryDirectory(prefix=f"vfdsl-build-{prefix}-"), exc
    else:
        fallback = None
    try:
        with work_dir as tmp:
            work = Path(tmp)
            source, header = _generate(fn, prefix, work, checks,
                                       input_checks if input_checks is not None else _no_input_checks(fn), phases,
                                       teleop)
            extra = tuple(Path(x) for x in extra_sources)
            digest = _digest(source + "".join(x.read_text() for x in extra), header, compiler, metadata)
            entry = cache_dir / f"{prefix}-{digest[:16]}"
            found = _verified(entry, prefix, digest)
            if found is not None:
                return dataclasses.replace(found, reused=True)
            built = _compile(fn, prefix, work, compiler, digest, metadata, extra)
            if fallback is not None:
                entry = _private_cache() / entry.name
                warnings.warn(f"cannot write the build cache {cache_dir} ({fallback.strerror}); "
                              f"built in {entry.parent} instead", BuildCacheUnwritable, stacklevel=3)
            return _publish(work, built, entry, prefix, digest)
    except OSError as exc:
        raise VfError(f"cannot write the build of {prefix}: {exc.strerror or exc} ({exc.filename or cache_dir})",
                      hint=f"free disk space, or point {CACHE_OPTIONS} at a writable directory") from None


class BuildCacheUnwritable(UserWarning):
    """The build cache could not be written: the library was built in a private temporary directory."""


def _private_cache() -> Path:
    """A per-user cache under the system's temporary directory (for a cache that cannot be written)."""
    path = Path(tempfile.gettempdir()) / f"vfdsl-cache-{os.getuid()}"
    path.mkdir(mode=0o700, exist_ok=True)
    return path


def find_compiler() -> Compiler:
    """The compiler named by ``$CC`` (default ``cc``), identified by version and resolved target."""
    try:
        command = tuple(shlex.split(os.environ.get("CC", "cc")))
    except ValueError as exc:
        raise CompilerUnavailable(f"CC={os.environ.get('CC')!r} does not parse as a command: {exc}",
                                  hint="quote CC as a shell would, e.g. CC='gcc -m64'") from None
    path = shutil.which(command[0]) if command else None
    if path is None:
        raise CompilerUnavailable(
            f"C compiler {os.environ.get('CC', 'cc')!r} not found",
            hint="install gcc or clang, set CC to a compiler, or use the interpreted runtime path")
    return _identify((path,) + command[1:], os.stat(path).st_mtime_ns)


@functools.lru_cache(maxsize=8)
def _identify(command: tuple[str, ...], _mtime_ns: int) -> Compiler:
    version = next(iter(_run([*command, "--version"]).stdout.splitlines()), "").strip()
    probe = _run([*command, *FLAGS, "-###", "-E", "-x", "c", os.devnull])  # -E: no temp file names
    target = hashlib.sha256(probe.stderr.encode()).hexdigest()
    return Compiler(command, version, target)


def _run(argv: list[str]) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(argv, capture_output=True, text=True, check=True)
    except OSError as e:
        raise CompilerUnavailable(f"cannot run C compiler {argv[0]!r}: {e}") from e
    except subprocess.CalledProcessError as e:
        raise CompilerUnavailable(f"C compiler {argv[0]!r} does not work: {_tail(e.stderr)}") from e


def _tail(text: str, lines: int = 25) -> str:
    return "\n".join(text.strip().splitlines()[-lines:])


def _generate(fn: ca.Function, prefix: str, work: Path, checks: ca.Function,
              input_checks: ca.Function, phases: PhaseCode | None = None,
              teleop: ca.Function | None = None) -> tuple[str, str]:
    """Write ``<prefix>.c``/``.h`` into ``work`` (the step exported as ``prefix``, the checks as
    ``<prefix>_admissible`` and ``<prefix>_input_checks``): CasADi's C patched for ``fn``'s solve plans, its header
    with vfdsl's contract and the C declarations of the tick's buffers (:mod:`vfdsl.codegen.tick_buffers`); a
    procedure's also its functions and machine (:func:`vfdsl.codegen.procedure_code.header`)."""
    extra = () if phases is None else procedure_code.functions(phases, prefix)
    if teleop is not None:
        extra += ((teleop, f"{prefix}_teleop_readout"),)
    source, header = casadi_c(fn, prefix, work, checks, input_checks, extra)
    source = patch_generated_c(source, prefix, plans_of(fn))
    contract = HEADER_CONTRACT.replace("@PREFIX@", prefix).replace("@SLOTS@", str(MAX_SLOTS))
    if phases is None:
        header += contract.replace("@CALL@", c_call()) + c_declarations(fn)
    else:
        header += procedure_code.header(fn, phases, contract)
    if teleop is not None:
        header += teleop_declarations(teleop)
    (work / f"{prefix}.c").write_text(source)
    (work / f"{prefix}.h").write_text(header)
    return source, header


def teleop_declarations(teleop: ca.Function) -> str:
    """The generated header's sizes of a teleoperated task's readout (codegen/teleop_readout.h)."""
    state, acting = teleop.numel_in(teleop.index_in("state")), teleop.numel_out(teleop.index_out("acting"))
    return (f"\n#ifndef VFDSL_TELEOP\n#define VFDSL_TELEOP 1\n#define VFDSL_TELEOP_STATE {state}\n"
            f"#define VFDSL_TELEOP_ROWS {acting}\n#endif\n")


def casadi_c(fn: ca.Function, prefix: str, work: Path, checks: ca.Function,
             input_checks: ca.Function | None = None,
             extra: tuple[tuple[ca.Function, str], ...] = ()) -> tuple[str, str]:
    """(C source, header) as CasADi generates them in ``work`` for ``fn`` exported as ``prefix``, ``checks`` as
    ``<prefix>_admissible``, ``input_checks`` (when given) as ``<prefix>_input_checks`` and each ``(function,
    name)`` of ``extra`` as ``name``, before vfdsl's patch."""
    generator = ca.CodeGenerator(f"{prefix}.c", {"with_header": True})
    generator.add(_renamed(fn, prefix))
    generator.add(_renamed(checks, f"{prefix}_admissible"))
    if input_checks is not None:
        generator.add(_renamed(input_checks, f"{prefix}_input_checks"))
    for function, name in extra:
        generator.add(_renamed(function, name))
    generator.generate(str(work) + os.sep)
    return (work / f"{prefix}.c").read_text(), (work / f"{prefix}.h").read_text()


def _no_input_checks(fn: ca.Function) -> ca.Function:
    """u -> an empty column: the step's inputs need no check beyond finiteness (which the C makes first)."""
    u = ca.SX.sym("u", fn.numel_in(fn.index_in("u")))
    return ca.Function("input_checks", [u], [ca.SX(0, 1)], ["u"], ["margins"])


def _renamed(fn: ca.Function, name: str) -> ca.Function:
    if fn.name() == name:
        return fn
    args = fn.mx_in()
    return ca.Function(name, args, fn.call(args), fn.name_in(), fn.name_out())


def task_flags() -> tuple[str, ...]:
    """FLAGS with the optimisation $VFDSL_OPTIMIZE asks for (:data:`OPTIMIZE`)."""
    level = os.environ.get(OPTIMIZE, "O3")
    if level not in ("O0", "O1", "O2", "O3"):
        raise VfError(f"${OPTIMIZE} is {level!r}, not an optimisation level",
                      hint=f"set {OPTIMIZE} to O3 (the default), O2, O1 or O0, or unset it")
    return (f"-{level}", *FLAGS[1:])


def _digest(source: str, header: str, compiler: Compiler, metadata: dict) -> str:
    key = json.dumps({"source": source, "header": header, "flags": task_flags(),
                      "compiler": compiler.version, "target": compiler.target,
                      "casadi": ca.__version__, "daqp": daqp_version(), "lexls": _LEXLS_KEY, "metadata": metadata,
                      "python_module": _python_build_key()}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()


@functools.lru_cache(maxsize=1)
def python_headers() -> tuple[str, ...] | None:
    """Include directories for building the Python extension (Python's and NumPy's), or None when
    Python.h is missing (a Python without its development headers): then only the C library is built."""
    import numpy
    include = sysconfig.get_paths().get("include")
    if not include or not (Path(include) / "Python.h").is_file():
        return None
    return include, numpy.get_include()


def _python_build_key() -> dict | None:
    """What the extension depends on besides the generated C: its source, the ABI, NumPy's C API."""
    if python_headers() is None:
        return None
    import numpy
    return {"stepper": [path.read_text() for path in STEPPER_PARTS], "checked_step": CHECKED_STEP.read_text(),
            "procedure_tick": [path.read_text() for path in PROCEDURE_TICK], "soabi": sysconfig.get_config_var("SOABI"),
            "numpy": numpy.__version__}


def _compile(fn: ca.Function, prefix: str, work: Path, compiler: Compiler, digest: str,
             metadata: dict, extra: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Compile in ``work``: the generated C once into an object, linked into the C library and (with
    Python headers) into the Python extension; check that both load; write the metadata; return it."""
    nonce = secrets.token_hex(4)
    so_name = f"lib{prefix}-{nonce}.so"
    root = daqp_sources(daqp_home())
    daqp = solver_libraries(compiler, fn.size1_out(0), root)
    flags = task_flags()
    _cc(compiler, work, [*flags, f"-I{root / 'include'}", "-c", f"{prefix}.c", "-o", f"{prefix}.o"])
    objects = [f"{prefix}.o"]
    for source in extra:     # kept in the entry (for `vfdsl export`); their symbols stay hidden in the library
        shutil.copyfile(source, work / source.name)
        objects.append(f"{source.stem}.o")
        _cc(compiler, work, [*flags, "-DVFM_EXPORT=", "-c", source.name, "-o", objects[-1]])
    _cc(compiler, work, [*flags, "-shared", *objects, "-o", so_name, *daqp])
    _load(work / so_name, prefix)
    module_file = None
    headers = python_headers()
    if headers is not None:
        module = f"{prefix}_py"
        module_file = f"{module}-{nonce}.so"
        _cc(compiler, work, [*flags, "-shared", *(f"-I{d}" for d in headers), f"-DVFDSL_PREFIX={prefix}",
                             f"-DVFDSL_MODULE={module}", "-include", f"{prefix}.h", str(STEPPER),
                             *objects, "-o", module_file, "-Wl,-Bsymbolic", *daqp])
        load_module(work / module_file)
    meta = {**metadata,
            "prefix": prefix, "digest": digest,
            "inputs": _io(fn.name_in(), fn.size_in), "outputs": _io(fn.name_out(), fn.size_out),
            "compiler": compiler.command[0], "compiler_version": compiler.version,
            "compiler_target_sha256": compiler.target, "flags": list(flags),
            "casadi_version": ca.__version__, "daqp_version": daqp_version(), "max_slots": MAX_SLOTS,
            "created": datetime.datetime.now(datetime.UTC).isoformat(),
            "so_file": so_name, "so_sha256": _sha256(work / so_name), "extra_sources": [x.name for x in extra],
            "c_sha256": _sha256(work / f"{prefix}.c"), "h_sha256": _sha256(work / f"{prefix}.h"),
            "python_module_file": module_file,
            "python_module_sha256": _sha256(work / module_file) if module_file else None}
    (work / f"{prefix}.json").write_text(json.dumps(meta, indent=2, sort_keys=True))
    return meta


def default_cache_dir() -> Path:
    """$VFDSL_CACHE, else $XDG_CACHE_HOME/vfdsl, else ~/.cache/vfdsl."""
    if os.environ.get("VFDSL_CACHE"):
        return Path(os.environ["VFDSL_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "vfdsl"


def daqp_home() -> Path:
    """Where DAQP's sources and static libraries are kept: the default cache (shared by every build cache that
    a caller names), or a private one when that cannot be written."""
    home = default_cache_dir()
    try:
        home.mkdir(parents=True, exist_ok=True)
        if os.access(home, os.W_OK | os.X_OK):
            return home
    except OSError:
        pass
    return _private_cache()


def daqp_library(compiler: Compiler, root: Path | None = None) -> Path:
    """DAQP's sources (in ``root``, default: :func:`daqp_sources` of :func:`daqp_home`) compiled with FLAGS by
    ``compiler`` into a static library (symbols hidden), built once per compiler, target and flags next to the
    sources (:mod:`vfdsl.codegen.daqp_sources`)."""
    root = root if root is not None else daqp_sources(daqp_home())
    key = hashlib.sha256(json.dumps([FLAGS, compiler.version, compiler.target]).encode()).hexdigest()[:16]
    library = root / "lib" / f"libdaqp-{key}.a"
    if not library.is_file():
        announce(f"building DAQP {daqp_version()}'s solver library with {Path(compiler.command[0]).name}")
    return _static_library(compiler, library, {f"{source.stem}.o": [f"-I{root / 'include' / 'daqp'}", str(source)]
                                               for source in source_files(root)})


def lexls_library(compiler: Compiler, n: int, root: Path | None = None) -> Path:
    """vfdsl's ``lexls.c`` compiled for problems of ``n`` variables (``-DVFDSL_LEX_N``: its loops then have known
    trip counts, which the compiler unrolls; experiment B's exact solve 1.47 -> 1.21 us) into a static library
    beside DAQP's (in ``root``, as :func:`daqp_library`), built once per compiler, target, flags, lexls.c and n.
    (lexls.c at -O3 takes ~1.4 s to compile, about as long as a task's whole generated C: compiled here, once per n,
    it is not compiled again for every task.)"""
    root = root if root is not None else daqp_sources(daqp_home())
    key = hashlib.sha256(json.dumps([FLAGS, compiler.version, compiler.target, _LEXLS_KEY]).encode()).hexdigest()[:16]
    return _static_library(compiler, root / "lib" / f"liblexls-n{n}-{key}.a",
                           {"vfdsl_lexls.o": [f"-DVFDSL_LEX_N={int(n)}", str(LEXLS_SOURCE)]})


def solver_libraries(compiler: Compiler, n: int, root: Path | None = None) -> list[str]:
    """The link arguments of a task's step with ``n`` variables: lexls for n, DAQP, libm, their symbols hidden (the
    libraries beside the sources in ``root``, as :func:`daqp_library`)."""
    root = root if root is not None else daqp_sources(daqp_home())
    return [str(lexls_library(compiler, n, root)), str(daqp_library(compiler, root)), "-lm",
            "-Wl,--exclude-libs,ALL"]


def _static_library(compiler: Compiler, library: Path, objects: dict[str, list[str]]) -> Path:
    """``library``, built if missing from ``objects`` (object name -> its compile arguments after FLAGS) in a
    private directory and published with one ``os.replace`` (processes racing on it each publish a whole one)."""
    if library.is_file():
        return library
    library.parent.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory(dir=library.parent, prefix=".build-") as tmp:
        for name, args in objects.items():
            _cc(compiler, Path(tmp), [*FLAGS, "-c", *args, "-o", name])
        archive = shutil.which("ar") or shutil.which("gcc-ar")
        if archive is None:
            raise CompilerUnavailable(f"no archiver (ar) found to build {library.name} (a static library of the "
                                      "QP solver)", hint="install binutils")
        result = subprocess.run([archive, "rcs", "lib.a", *objects], cwd=tmp, capture_output=True, text=True)
        if result.returncode != 0:
            raise VfError(f"ar failed on the objects of {library.name}: {_tail(result.stderr)}")
        os.replace(Path(tmp) / "lib.a", library)
    return library


def _cc(compiler: Compiler, work: Path, args: list[str]) -> None:
    argv = [*compiler.command, *args]
    result = subprocess.run(argv, cwd=work, capture_output=True, text=True)
    if result.returncode != 0:
        raise VfError(f"the C compiler failed ({shlex.join(argv)}):\n{_tail(result.stderr)}")


def _io(names: list[str], size) -> list[dict[str, Any]]:
    return [{"name": name, "shape": list(size(i))} for i, name in enumerate(names)]


def _publish(work: Path, meta: dict, entry: Path, prefix: str, digest: str) -> BuiltLibrary:
    """Move the finished build to ``entry`` atomically, replacing an invalid entry if any."""
    staged = work / "entry"
    staged.mkdir()
    files = [f"{prefix}.c", f"{prefix}.h", meta["so_file"], f"{prefix}.json", *meta["extra_sources"]]
    for name in files + ([meta["python_module_file"]] if meta["python_module_file"] else []):
        os.replace(work / name, staged / name)
    for _ in range(3):
        try:
            os.replace(staged, entry)
            return _library(entry, prefix, digest, meta)
        except OSError:  # entry exists: another process won the race, or it is invalid
            found = _verified(entry, prefix, digest)
            if found is not None:
                return found
        with contextlib.suppress(FileNotFoundError):  # another process may have moved it first
            os.replace(entry, work / f"invalid-{secrets.token_hex(4)}")
    raise VfError(f"could not publish {entry}: it keeps being replaced by other processes")


def _verified(entry: Path, prefix: str, digest: str) -> BuiltLibrary | None:
    """The library in ``entry`` if it is complete, uncorrupted and loadable, else None."""
    try:
        meta = json.loads((entry / f"{prefix}.json").read_text())
        library = _library(entry, prefix, digest, meta)
        intact = (meta["digest"] == digest and library.so_path.parent == entry
                  and _sha256(library.c_path) == meta["c_sha256"]
                  and _sha256(library.h_path) == meta["h_sha256"]
                  and _sha256(library.so_path) == meta["so_sha256"]
                  and (library.module_path is None
                       or _sha256(library.module_path) == meta["python_module_sha256"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not intact:
        return None
    try:
        _load(library.so_path, prefix)
        if library.module_path is not None:
            load_module(library.module_path)
    except VfError:
        return None
    return library


def _library(entry: Path, prefix: str, digest: str, meta: dict) -> BuiltLibrary:
    module = meta["python_module_file"]
    return BuiltLibrary(so_path=entry / meta["so_file"], c_path=entry / f"{prefix}.c",
                        h_path=entry / f"{prefix}.h", meta_path=entry / f"{prefix}.json",
                        digest=digest, module_path=entry / module if module else None)


def _load(so_path: Path, prefix: str) -> None:
    try:
        getattr(ctypes.CDLL(str(so_path)), prefix)
    except (OSError, AttributeError) as e:
        raise VfError(f"{so_path} does not load or lacks symbol {prefix!r}: {e}") from e


def load_module(path: Path):
    """The Python extension at ``path`` (module name: the file name up to its first '-')."""
    name = Path(path).name.split("-")[0]
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.Stepper  # noqa: B018 - the type the runtime needs
    except (ImportError, AttributeError, OSError) as e:
        raise VfError(f"{path} does not load as a Python extension: {e}") from e
    return module


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
