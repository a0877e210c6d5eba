"""The build and its cache never crash a command: bad places, bad compilers, damaged entries, long names."""

from __future__ import annotations

import errno
import os
import subprocess
import tempfile
import warnings

import pytest

import vfdsl
from vfdsl import pipeline
from vfdsl.cli import main as cli_main
from vfdsl.codegen import build as codegen
from vfdsl.codegen import daqp_sources as sources
from vfdsl.errors import VfError
from conftest import REPO, TASKS_DIR

B = TASKS_DIR / "paper_b_virtual_rcm.vf"


@pytest.fixture(scope="module")
def task_b():
    return vfdsl.load(B)


def test_a_cache_path_that_is_a_file_or_device_is_a_clear_error(tmp_path, task_b, capsys):
    not_a_dir = tmp_path / "cache"
    not_a_dir.write_text("")
    with pytest.raises(VfError, match="is not a directory"):
        pipeline.build(task_b, backend="native", cache_dir=not_a_dir)
    for target in (str(not_a_dir), os.devnull):
        assert cli_main(["compile", str(B), "-o", target]) == 2
        err = capsys.readouterr().err
        assert "is not a directory" in err and "Traceback" not in err


def test_an_unwritable_cache_uses_its_valid_entry_or_builds_elsewhere(tmp_path, task_b, monkeypatch):
    cache = tmp_path / "cache"
    _, first = pipeline.build(task_b, backend="native", cache_dir=cache)
    real = tempfile.TemporaryDirectory

    def read_only(*args, dir=None, **kwargs):      # the tests run as root: simulate EROFS
        if dir is not None and str(dir).startswith(str(cache)):
            raise OSError(errno.EROFS, "Read-only file system", str(dir))
        return real(*args, **kwargs)

    monkeypatch.setattr(codegen.tempfile, "TemporaryDirectory", read_only)
    ctrl, again = pipeline.build(task_b, backend="native", cache_dir=cache)
    assert again.reused and again.so_path == first.so_path                  # the valid entry is used
    changed = task_b.model_copy(update={"name": "paper_b_changed"})
    with pytest.warns(codegen.BuildCacheUnwritable, match="built in"):
        ctrl, elsewhere = pipeline.build(changed, backend="native", cache_dir=cache)
    assert not str(elsewhere.so_path).startswith(str(cache))
    assert ctrl.step(task_b.start, {"tau": [0, 0, 0.01]}).shape == (7,)


def test_a_full_disk_is_a_clear_error(tmp_path, task_b, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x.o"))

    monkeypatch.setattr(codegen, "_compile", full)
    with pytest.raises(VfError, match="No space left on device"):
        pipeline.build(task_b, backend="native", cache_dir=tmp_path / "cache")


def test_a_corrupt_cached_source_is_rebuilt(tmp_path, task_b, capsys):
    cache = tmp_path / "cache"
    _, first = pipeline.build(task_b, backend="native", cache_dir=cache)
    first.c_path.write_bytes(b"\xff\xfe\x00 not C")
    _, second = pipeline.build(task_b, backend="native", cache_dir=cache)
    assert not second.reused and second.c_path.read_text().startswith("/*")
    assert cli_main(["compile", str(B), "-o", str(cache)]) == 0


def test_a_cc_that_does_not_parse_falls_back_or_is_a_clear_error(tmp_path, task_b, monkeypatch):
    monkeypatch.setenv("CC", 'gcc "-O2')
    with pytest.raises(VfError, match="does not parse"):
        pipeline.build(task_b, backend="native", cache_dir=tmp_path)
    monkeypatch.setattr(pipeline, "_warned", False)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        ctrl = vfdsl.compile(task_b, cache_dir=tmp_path)
    assert ctrl.backend == "interpreted" and any("does not parse" in str(w.message) for w in seen)


def test_a_task_name_longer_than_a_file_name_builds(tmp_path, task_b):
    """The front end caps names at 100 characters; an IR built in Python may have any name."""
    task = task_b.model_copy(update={"name": "long_name_" * 40})
    prefix = pipeline.symbol_prefix(task)
    assert len(prefix) <= 3 + pipeline.NAME_IN_SYMBOL + 9
    _, library = pipeline.build(task, backend="native", cache_dir=tmp_path / "cache")
    assert library.so_path.is_file()


def test_missing_daqp_sources_fall_back_or_are_a_clear_error(tmp_path, task_b, monkeypatch):
    """No DAQP sources (an offline machine, a wrong VFDSL_DAQP_SDIST): the native backend says so and how to give
    them; 'auto' runs interpreted, with a warning."""
    monkeypatch.setenv("VFDSL_CACHE", str(tmp_path / "fresh"))          # no sources fetched there yet
    monkeypatch.setenv("VFDSL_DAQP_SDIST", str(tmp_path / "missing.tar.gz"))
    with pytest.raises(VfError, match="cannot read .*missing.tar.gz"):
        pipeline.build(task_b, backend="native", cache_dir=tmp_path / "build")
    monkeypatch.setattr(pipeline, "_warned", False)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        ctrl = vfdsl.compile(task_b, cache_dir=tmp_path / "build")
    assert ctrl.backend == "interpreted" and any("running the controller interpreted" in str(w.message) for w in seen)


def test_a_daqp_archive_that_is_not_the_recorded_one_is_refused(tmp_path, task_b, monkeypatch):
    fake = tmp_path / "daqp-0.11.0.tar.gz"
    fake.write_bytes(b"not DAQP")
    monkeypatch.setenv("VFDSL_CACHE", str(tmp_path / "fresh"))
    monkeypatch.setenv("VFDSL_DAQP_SDIST", str(fake))
    with pytest.raises(VfError, match="is not DAQP 0.11.0's source distribution"):
        pipeline.build(task_b, backend="native", cache_dir=tmp_path / "build")
    assert not (tmp_path / "fresh" / "daqp-0.11.0").exists()


def test_no_archiver_is_a_clear_error_and_leaves_no_half_library(tmp_path, monkeypatch):
    """Without ar (binutils), building a solver library says so and how to fix it, and publishes nothing."""
    which = codegen.shutil.which
    monkeypatch.setattr(codegen.shutil, "which", lambda name: None if name in ("ar", "gcc-ar") else which(name))
    with pytest.raises(codegen.CompilerUnavailable, match=r"no archiver \(ar\) found to build liblexls-n3-") as info:
        codegen.lexls_library(codegen.find_compiler(), 3, tmp_path)
    assert "binutils" in str(info.value.hint)
    assert not list((tmp_path / "lib").iterdir())


def test_fetching_daqp_asks_pip_for_daqp_alone_and_says_so(tmp_path, monkeypatch, capsys):
    """The first controller on a machine fetches DAQP's sdist with `--no-binary daqp`: `--no-binary :all:` made pip
    build daqp's build requirements (Cython among them) from source just to prepare its metadata, 368 s on a fresh
    2-core machine with nothing printed. Fetching says so in one line on stderr; an index that cannot be reached
    is a clear error naming the command (the README's), for a machine that can reach it."""
    calls = []

    def unreachable(argv, **kwargs):
        calls.append(argv)
        return subprocess.CompletedProcess(argv, 1, "", "WARNING: retrying\nERROR: No matching distribution found\n")

    monkeypatch.delenv("VFDSL_DAQP_SDIST", raising=False)
    monkeypatch.setattr(sources.subprocess, "run", unreachable)
    with pytest.raises(sources.DaqpSourcesUnavailable, match="cannot download DAQP 0.11.0's C sources") as info:
        sources.daqp_sources(tmp_path)
    [argv] = calls
    assert argv[argv.index("--no-binary") + 1] == "daqp" and ":all:" not in argv
    assert {"download", "--no-deps", "daqp==0.11.0"} <= set(argv)
    assert str(info.value.message).endswith(": ERROR: No matching distribution found")
    command = "pip download --no-deps --no-binary daqp daqp==0.11.0"
    assert command in info.value.hint and command in (REPO / "README.md").read_text()
    assert capsys.readouterr().err == "vfdsl: fetching DAQP 0.11.0's C sources with pip (once) ...\n"
    assert not (tmp_path / "daqp-0.11.0").exists()


def test_building_daqp_says_so_once(tmp_path, monkeypatch, capsys):
    """Building DAQP's static library (tens of seconds on a loaded machine) says so in one line, only when it is
    built: a library already in the cache is used silently."""
    built = []
    monkeypatch.setattr(codegen, "_static_library", lambda compiler, library, objects: built.append(library) or library)
    compiler = codegen.Compiler(("cc",), "cc (test) 1.0", "x86_64")
    library = codegen.daqp_library(compiler, tmp_path)
    assert capsys.readouterr().err == "vfdsl: building DAQP 0.11.0's solver library with cc (once) ...\n"
    library.parent.mkdir(parents=True)
    library.write_bytes(b"")
    assert codegen.daqp_library(compiler, tmp_path) == library and len(built) == 2
    assert capsys.readouterr().err == ""
