"""The phase machine in C (vfdsl/codegen/phase_machine.h, through tests/phase_machine_harness.c) takes the same
decisions as vfdsl.runtime.phase_machine, to the last bit (built with the generated tick's flags, and at -O0), on
thousands of random tables and random sequences of compiled values (NaN among them), inputs (held, changing,
NaN), dt (constant, jittered, 0, not finite) and statuses; and on every one of them the weights lie in [0, 1] and
sum to 1, and a tick whose compiled values are all NaN fires no transition of a machine whose monitors are all
comparisons."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np
import pytest

from vfdsl.codegen.build import FLAGS, CompilerUnavailable, find_compiler
from vfdsl.runtime import phase_machine as pm
from vfdsl.runtime.qp import StepStatus

HARNESS = Path(__file__).with_name("phase_machine_harness.c")
CODEGEN = HARNESS.parent.parent / "vfdsl" / "codegen"
CONSTANTS = (pm.FALSE, pm.TRUE, pm.UNKNOWN, pm.COMPARE, pm.ELAPSED, pm.UNCHANGED, pm.LEAST_VIOLATION, pm.LOGIC,
             pm.GT, pm.GE, pm.LT, pm.LE, pm.AND, pm.OR, pm.NOT, pm.MAX_STACK, pm.LEAST_VIOLATION_BIT)
TABLES = 2000


@pytest.fixture(scope="module", params=["generated", "plain"])
def harness(request, tmp_path_factory):
    """The harness built with the generated tick's flags (its symbols visible), or with -O0."""
    try:
        command = find_compiler().command
    except CompilerUnavailable:
        pytest.skip("needs a C compiler")
    flags = [f for f in FLAGS if f != "-fvisibility=hidden"] if request.param == "generated" else ["-O0"]
    so = tmp_path_factory.mktemp("phase_machine") / "harness.so"
    subprocess.run([*command, *flags, "-std=c99", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC", f"-I{CODEGEN}",
                    str(HARNESS), "-o", str(so), "-lm"], check=True, capture_output=True, text=True)
    return ctypes.CDLL(str(so))


def program(rng, monitors: int, depth: int = 0) -> list[int]:
    """A random postfix expression over monitors [0, monitors)."""
    if depth > 3 or rng.random() < 0.45:
        return [int(rng.integers(monitors))]
    if rng.random() < 0.25:
        return [*program(rng, monitors, depth + 1), pm.NOT]
    return [*program(rng, monitors, depth + 1), *program(rng, monitors, depth + 1), int(rng.choice([pm.AND, pm.OR]))]


def random_table(rng, kinds=(pm.COMPARE, pm.ELAPSED, pm.UNCHANGED, pm.LEAST_VIOLATION, pm.LOGIC)):
    phases, raw_size, u_size = (int(n) for n in rng.integers(1, 6, 3))
    watched = tuple((int(s), int(rng.integers(1, u_size - s + 1))) for s in rng.integers(0, u_size, rng.integers(0, 3)))
    monitors = []
    for i in range(int(rng.integers(1, 9))):
        kind = int(rng.choice([k for k in kinds if (k != pm.UNCHANGED or watched) and (k != pm.LOGIC or i)]))
        raw = int(rng.integers(raw_size))
        release = int(rng.integers(raw_size)) if rng.random() < 0.4 else -1
        hold = 0.0 if rng.random() < 0.4 else float(rng.choice([1e-3, 2.5e-3, 7e-3]) * rng.integers(1, 12))
        monitors.append(pm.Monitor(kind, raw=raw if kind == pm.COMPARE else -1,
                                   release=release if kind == pm.COMPARE else -1,
                                   watch=int(rng.integers(len(watched))) if kind == pm.UNCHANGED else -1,
                                   op=int(rng.integers(4)), threshold=float(rng.uniform(0, 0.02)),
                                   program=tuple(program(rng, i)) if kind == pm.LOGIC else (), hold=hold))
    transitions = tuple(pm.Transition(int(rng.integers(-1, phases)), int(rng.integers(phases)),
                                      tuple(program(rng, len(monitors))),
                                      0.0 if rng.random() < 0.3 else float(rng.uniform(0, 0.03)))
                        for _ in range(int(rng.integers(0, 9))))
    final = tuple(bool(f) for f in rng.random(phases) < 0.2)
    return pm.MachineTable(int(rng.integers(phases)), final, tuple(monitors), watched, transitions, raw_size, u_size)


def random_ticks(rng, table, ticks):
    """(raw, u, dt, status) per tick: compiled values drifting across 0 (so that holds and latches play), a few
    NaN; inputs held for stretches; dt constant, jittered or odd."""
    raw = np.cumsum(rng.normal(scale=0.3, size=(ticks, table.raw_size)), axis=0) + rng.normal(size=table.raw_size)
    raw[rng.random(raw.shape) < 0.02] = np.nan
    held = rng.integers(0, 4, size=(ticks, table.u_size)) * (rng.random((ticks, table.u_size)) < 0.15)
    u = np.cumsum(held, axis=0).astype(float)
    u[rng.random(u.shape) < 0.01] = np.nan
    dt = np.full(ticks, float(rng.choice([1e-3, 2.5e-3, 3e-3])))
    if rng.random() < 0.3:
        dt *= rng.uniform(0.5, 1.5, ticks)
    odd = rng.random(ticks) < 0.01
    dt[odd] = rng.choice([0.0, -1e-3, np.nan, np.inf], odd.sum())
    status = rng.integers(0, 8, ticks) * (rng.random(ticks) < 0.2)
    return raw, u, dt, status.astype(np.intc)


def python_run(table, raw, u, dt, status):
    state = pm.MachineState.initial(table)
    out = {"phase": [], "fired": [], "weight": [], "funnel": [], "value": []}
    for k in range(len(dt)):
        out["fired"].append(pm.advance(table, state, list(raw[k]), list(u[k]), float(dt[k]), int(status[k])))
        out["phase"].append(state.phase)
        out["weight"].append(list(state.weight))
        out["funnel"].append(state.funnel)
        out["value"].append(list(state.value))
    return {name: np.array(v, dtype=float if name in ("weight", "funnel") else np.intc) for name, v in out.items()}


def c_run(lib, table, raw, u, dt, status):
    arrays = table.c_arrays()
    ints = lambda name: np.array(arrays[name] or [0], dtype=np.intc)            # noqa: E731
    doubles = lambda name: np.array(arrays[name] or [0.0], dtype=float)         # noqa: E731
    ticks, n, phases = len(dt), len(table.monitors), table.phases
    state = [np.zeros(max(size, 1), dtype) for size, dtype in (
        (n, np.intc), (n, np.intc), (n, float), (sum(s for _, s in table.watched), float),
        (len(table.watched), float), (phases, float), (phases, float))]
    out = {"phase": np.zeros(ticks, np.intc), "fired": np.zeros(ticks, np.intc),
           "weight": np.zeros((ticks, phases)), "funnel": np.zeros(ticks), "value": np.zeros((ticks, n), np.intc)}
    keep = [ints("final"), ints("kind"), ints("a"), ints("b"), ints("op"), doubles("threshold"), doubles("hold"),
            ints("watch_start"), ints("watch_size"), ints("watch_offset"), ints("source"), ints("target"),
            ints("guard_start"), ints("guard_size"), doubles("blend"), ints("code"),
            *(np.ascontiguousarray(a) for a in (raw, u, dt, status))]
    p = [a.ctypes.data_as(ctypes.c_void_p) for a in keep]
    c = ctypes.c_int
    lib.pm_run(c(phases), c(table.initial), p[0], c(n), *p[1:7], c(len(table.watched)), *p[7:10],
               c(len(table.transitions)), *p[10:16], c(ticks), c(table.raw_size), c(table.u_size), *p[16:20],
               *(a.ctypes.data_as(ctypes.c_void_p) for a in state),
               *(out[name].ctypes.data_as(ctypes.c_void_p) for name in ("phase", "fired", "weight", "funnel",
                                                                         "value")))
    return out


def test_the_header_has_the_modules_constants(harness):
    out = np.zeros(len(CONSTANTS), np.intc)
    harness.pm_constants(out.ctypes.data_as(ctypes.c_void_p))
    assert tuple(out) == CONSTANTS and pm.LEAST_VIOLATION_BIT == StepStatus.LEAST_VIOLATION


def test_c_and_python_take_the_same_decisions(harness):
    rng = np.random.default_rng(33)
    fired = blended = 0
    for _ in range(TABLES):
        table = random_table(rng)
        ticks = random_ticks(rng, table, int(rng.integers(50, 300)))
        py, c = python_run(table, *ticks), c_run(harness, table, *ticks)
        for name in py:
            assert np.array_equal(py[name], c[name]), name
        w = py["weight"]
        assert np.all((w >= 0) & (w <= 1)) and np.allclose(w.sum(axis=1), 1, rtol=0, atol=1e-14)
        assert np.all((py["funnel"] >= 0) & (py["funnel"] <= 1))
        fired += np.count_nonzero(py["fired"] >= 0)
        blended += np.count_nonzero((w > 0) & (w < 1))
    assert fired > 10 * TABLES and blended > 10 * TABLES      # the cases exercise transitions and blends


def test_all_nan_compiled_values_fire_nothing(harness):
    """Monitors over compiled comparisons only (with holds, latches and programs of any shape, ``not`` included):
    a tick whose values are all NaN fires no transition, in C and in Python, and no weight is NaN."""
    rng = np.random.default_rng(34)
    nan_ticks = 0
    for _ in range(TABLES // 4):
        table = random_table(rng, kinds=(pm.COMPARE, pm.LOGIC))
        raw, u, dt, status = random_ticks(rng, table, 200)
        nan = rng.random(len(dt)) < 0.2
        raw[nan] = np.nan
        py, c = python_run(table, raw, u, dt, status), c_run(harness, table, raw, u, dt, status)
        assert np.array_equal(py["fired"], c["fired"]) and np.array_equal(py["weight"], c["weight"])
        assert np.all(py["fired"][nan] == -1) and not np.isnan(py["weight"]).any()
        assert np.all(py["value"][nan] != pm.TRUE)
        nan_ticks += nan.sum()
    assert nan_ticks > 1000
