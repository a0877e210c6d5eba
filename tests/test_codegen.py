"""Generate, compile, cache: hits, invalidation, concurrent builders, missing compiler, prefixes."""

from __future__ import annotations

import json
import multiprocessing
import os
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from vfdsl.codegen import CompilerUnavailable, build_library
from vfdsl.codegen import build as build_module
from vfdsl.errors import VfError
from vfdsl.runtime import BufferedFunction, build_step_function

NO_CHECKS = ca.Function("admissible", [ca.SX.sym("p", 0)], [ca.SX(0, 1)])   # params that need no check
ARGS = (np.array([0.3, -0.2]), np.array([0.2, 0.05]), np.array([0.05]), np.array([0.01]), 0.0)


def small_step(prefix: str, weight: float = 1.0, native: bool = True) -> ca.Function:
    """A 2-joint tick with one row x0 + x1 <= p and speed bounds 10 dt; ``weight`` scales H; ``native``: for
    build_library, else for CasADi's evaluation."""
    q, u, p, dt = ca.SX.sym("q", 2), ca.SX.sym("u", 2), ca.SX.sym("p", 1), ca.SX.sym("dt")
    H = weight * (ca.SX.eye(2) + 0.1 * ca.diag(ca.cos(q)))
    qp_data = ca.Function("qp", [q, u, p, dt], [H, -u, ca.DM([[1, 1]]), -ca.inf, p,
                                                -10 * dt * ca.DM.ones(2), 10 * dt * ca.DM.ones(2)],
                          ["q", "u", "p", "dt"], ["H", "g", "A", "lba", "uba", "lbx", "ubx"])
    return build_step_function(qp_data, prefix, native=native)


def evaluate(library, prefix: str) -> np.ndarray:
    return BufferedFunction.native(library.so_path, prefix)(*ARGS)[0].copy()


@pytest.fixture
def compiles(monkeypatch) -> list[str]:
    """Records the prefix of every compiler run."""
    calls: list[str] = []
    original = build_module._compile

    def counting(fn, prefix, *rest):
        calls.append(prefix)
        return original(fn, prefix, *rest)

    monkeypatch.setattr(build_module, "_compile", counting)
    return calls


@pytest.fixture(scope="module")
def interpreted_x() -> np.ndarray:
    return BufferedFunction.interpreted(small_step("ref", native=False))(*ARGS)[0].copy()


def test_build_then_hit(tmp_path, compiles, interpreted_x):
    first = build_library(small_step("vf_a"), "vf_a", tmp_path, {"task": "a"}, NO_CHECKS)
    mtime = first.so_path.stat().st_mtime_ns
    second = build_library(small_step("vf_a"), "vf_a", tmp_path, {"task": "a"}, NO_CHECKS)  # rebuilt graph
    assert compiles == ["vf_a"]
    assert not first.reused and second.reused
    assert second.so_path == first.so_path and second.digest == first.digest
    assert first.so_path.stat().st_mtime_ns == mtime
    meta = json.loads(first.meta_path.read_text())
    assert meta["task"] == "a" and meta["digest"] == first.digest
    assert meta["inputs"][0] == {"name": "q", "shape": [2, 1]}
    assert meta["outputs"][2] == {"name": "violation", "shape": [1, 1]}
    assert {"compiler", "compiler_version", "flags", "casadi_version", "created"} <= meta.keys()
    assert f"-{os.environ.get('VFDSL_OPTIMIZE', 'O3')}" in meta["flags"]        # (the suite builds at O0)
    assert "vf_a(const casadi_real** arg" in first.h_path.read_text()
    np.testing.assert_allclose(evaluate(first, "vf_a"), interpreted_x, atol=1e-12)


def test_changed_function_or_metadata_gets_a_new_entry(tmp_path, compiles):
    base = build_library(small_step("vf_b"), "vf_b", tmp_path, {}, NO_CHECKS)
    heavier = build_library(small_step("vf_b", weight=2.0), "vf_b", tmp_path, {}, NO_CHECKS)
    relabelled = build_library(small_step("vf_b"), "vf_b", tmp_path, {"labels": ["r0"]}, NO_CHECKS)
    assert len({base.digest, heavier.digest, relabelled.digest}) == 3
    assert len(compiles) == 3


def truncate(library):
    data = library.so_path.read_bytes()
    replacement = library.so_path.with_suffix(".partial")
    replacement.write_bytes(data[: len(data) // 2])
    os.replace(replacement, library.so_path)  # new inode: the copy this process mapped stays intact


def corrupt_metadata(library):
    library.meta_path.write_text(library.meta_path.read_text()[:40])


def edit_digest(library):
    meta = json.loads(library.meta_path.read_text())
    library.meta_path.write_text(json.dumps({**meta, "digest": "0" * 64}))


def remove_header(library):
    library.h_path.unlink()


@pytest.mark.parametrize("damage", [truncate, corrupt_metadata, edit_digest, remove_header])
def test_damaged_entry_is_rebuilt(tmp_path, compiles, interpreted_x, damage):
    library = build_library(small_step("vf_c"), "vf_c", tmp_path, {}, NO_CHECKS)
    damage(library)
    assert_rebuilt(library, tmp_path, interpreted_x)
    assert compiles == ["vf_c", "vf_c"]


def test_unloadable_library_is_rebuilt(tmp_path, compiles, interpreted_x):
    """A .so whose recorded hash matches but which does not load (e.g. a forged or foreign file).

    Built in another process: glibc would hand this one the library it loaded from that path.
    """
    library = run_in_children(build_in_child, 1, tmp_path, "vf_c")[0][0]
    replacement = library.so_path.with_suffix(".partial")
    replacement.write_bytes(b"\x7fELF not really a library")
    os.replace(replacement, library.so_path)
    meta = json.loads(library.meta_path.read_text())
    meta["so_sha256"] = build_module._sha256(library.so_path)
    library.meta_path.write_text(json.dumps(meta))
    assert_rebuilt(library, tmp_path, interpreted_x)
    assert compiles == ["vf_c"]


def assert_rebuilt(library, cache_dir, interpreted_x):
    rebuilt = build_library(small_step("vf_c"), "vf_c", cache_dir, {}, NO_CHECKS)
    assert rebuilt.digest == library.digest and rebuilt.so_path != library.so_path
    assert [p.name for p in cache_dir.iterdir()] == [library.so_path.parent.name]  # no leftovers
    np.testing.assert_allclose(evaluate(rebuilt, "vf_c"), interpreted_x, atol=1e-12)


def build_in_child(cache_dir: str, prefix: str, start, results) -> None:
    start.wait()
    library = build_library(small_step(prefix), prefix, Path(cache_dir), {}, NO_CHECKS)
    results.put((library, evaluate(library, prefix)))


def run_in_children(target, count: int, cache_dir: Path, prefix: str) -> list:
    """Start ``count`` fresh processes together on ``target``; return what each put in the queue."""
    context = multiprocessing.get_context("spawn")
    start, results = context.Barrier(count), context.Queue()
    children = [context.Process(target=target, args=(str(cache_dir), prefix, start, results))
                for _ in range(count)]
    for child in children:
        child.start()
    outcomes = [results.get(timeout=60) for _ in children]
    for child in children:
        child.join(timeout=60)
        assert child.exitcode == 0
    return outcomes


def test_two_processes_build_the_same_entry(tmp_path, interpreted_x):
    outcomes = run_in_children(build_in_child, 2, tmp_path, "vf_race")
    for library, x in outcomes:
        assert library.so_path.is_file()
        np.testing.assert_allclose(x, interpreted_x, atol=1e-12)
    assert [p.name for p in tmp_path.iterdir()] == [outcomes[0][0].so_path.parent.name]


def test_the_optimisation_is_in_the_key_and_changes_no_answer(tmp_path, monkeypatch):
    """$VFDSL_OPTIMIZE: O3 by default, O0 for the suite (tests/conftest.py). Each level is its own cache entry, and
    paper B's closed loop (300 ticks, a torque that sweeps the cone) is the same to the bit at O0 and O3: IEEE
    arithmetic at every level (-ffp-contract=off, never -ffast-math). A level that is not one is refused.
    (The entries go to a folder of this test, DAQP's library stays in the session's cache: a fresh $VFDSL_CACHE
    would fetch and build DAQP again, 30 s.)"""
    import vfdsl
    from conftest import TASKS_DIR
    task = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    runs = {}
    for level in ("O0", "O3"):
        monkeypatch.setenv("VFDSL_OPTIMIZE", level)
        ctrl = vfdsl.compile(task, cache_dir=tmp_path)
        q, trajectory = task.start.copy(), []
        for k in range(300):
            q = q + ctrl.step(q, {"tau": [0.01, 0.004 * np.cos(0.05 * k), 0.002]})
            trajectory.append(q.copy())
        runs[level] = np.array(trajectory)
    assert len(list(tmp_path.glob("vf_paper_b_virtual_rcm_*"))) == 2
    assert np.array_equal(runs["O0"], runs["O3"])
    monkeypatch.setenv("VFDSL_OPTIMIZE", "fast")
    with pytest.raises(VfError, match="VFDSL_OPTIMIZE"):
        vfdsl.compile(task, cache_dir=tmp_path)


def test_missing_compiler(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(CompilerUnavailable, match="not found"):
        build_library(small_step("vf_d"), "vf_d", tmp_path, {}, NO_CHECKS)


def test_compiler_error_carries_its_stderr(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", "cc -include /nonexistent/header.h")
    with pytest.raises(VfError, match="nonexistent/header.h") as error:
        build_library(small_step("vf_e"), "vf_e", tmp_path, {}, NO_CHECKS)
    assert not isinstance(error.value, CompilerUnavailable)


def test_bad_prefix(tmp_path):
    with pytest.raises(ValueError, match="C identifier"):
        build_library(small_step("x"), "not-an-identifier", tmp_path, {}, NO_CHECKS)


def test_two_prefixes_in_one_process(tmp_path):
    """Same structure, different data, different prefixes: both loaded, each keeps its own answer.

    The second function is named differently from its prefix, so it is exported under the prefix.
    """
    light = build_library(small_step("vf_light"), "vf_light", tmp_path, {}, NO_CHECKS)
    heavy = build_library(small_step("other_name", weight=4.0), "vf_heavy", tmp_path, {}, NO_CHECKS)
    light_fn = BufferedFunction.native(light.so_path, "vf_light")
    heavy_fn = BufferedFunction.native(heavy.so_path, "vf_heavy")
    expected_light = BufferedFunction.interpreted(small_step("l"))(*ARGS)[0].copy()
    expected_heavy = BufferedFunction.interpreted(small_step("h", weight=4.0))(*ARGS)[0].copy()
    assert not np.allclose(expected_light, expected_heavy)
    for _ in range(3):
        np.testing.assert_allclose(light_fn(*ARGS)[0], expected_light, atol=1e-12)
        np.testing.assert_allclose(heavy_fn(*ARGS)[0], expected_heavy, atol=1e-12)
