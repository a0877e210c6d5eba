"""`vfdsl export`: the exported folder builds with a C compiler and make alone and runs as Controller.step() does.

Every example task is exported once and built with ``make`` in a temporary folder, with a clean environment (no
Python or CasADi include paths; the folder's Makefile names only its own directories). Its ``replay`` runs ticks
recorded from ``Controller.step()`` (backend "native") on a closed loop: statuses equal, dq within 1e-12; 2,000
ticks for the paper's experiments A and B, 200 for the others. Bad values are refused with the right code and dq
zeros, and the params' checks refuse exactly what Python refuses (same check index). tests/export_contract.c
checks, on experiments A and B and on the mesh example sinus_channel (its proximity query walks in the work
arrays ``_new`` allocates), leaks under AddressSanitizer, heap calls after ``_new``, two controllers in two
threads, one controller from two threads.
"""

from __future__ import annotations

import ctypes
import dataclasses
import filecmp
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl import pipeline
from vfdsl.cli import main
from vfdsl.compiler.admissible import Admissible
from vfdsl.compiler.context import ParamLayout
from vfdsl.errors import VfError
from vfdsl.export import Export, api_name, export
from vfdsl.export.selftest import MAX_TICKS, Tick, build, check_count, record, replay
from vfdsl.export.writer import cpp_class_name
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus

pytestmark = pytest.mark.skipif(shutil.which("make") is None or shutil.which("cc") is None,
                                reason="needs make and a C compiler")

CONTRACT = Path(__file__).with_name("export_contract.c")
TASKS = sorted(path.stem for path in TASKS_DIR.glob("*.vf"))
EXPERIMENTS = ("paper_a_follow_curve", "paper_b_virtual_rcm")
CONTRACT_TASKS = (*EXPERIMENTS, "sinus_channel")
TASKS_WITH_PARAMS = [name for name in TASKS if ParamLayout(vfdsl.load(TASKS_DIR / f"{name}.vf").params).size]
CLEAN_ENV = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "LANG": "C"}
"""make's environment: no CPATH, C_INCLUDE_PATH or CFLAGS from this (Python) session."""
TEST_CFLAGS = "-O0"
"""The exports' builds in the tests, at the level the suite builds every task's C (tests/conftest.py,
$VFDSL_OPTIMIZE): about 4 times faster than the Makefile's -O3, and arithmetic without -ffast-math gives the same
answers at any level. The Makefile's own default (-O3) is built for DEFAULT_BUILD."""
DEFAULT_BUILD = "paper_b_virtual_rcm"


def make(directory: Path, cflags: str | None = TEST_CFLAGS) -> None:
    """The export's own Makefile in ``directory``, in a clean environment, with CFLAGS=``cflags`` (None: its own)."""
    subprocess.run(["make", "-s", "-j2", *([f"CFLAGS={cflags}"] if cflags else [])], cwd=directory, env=CLEAN_ENV,
                   check=True, capture_output=True)

# Error codes of vf_<task>.h
ERR_Q_NONFINITE, ERR_Q_RANGE, ERR_INPUT, ERR_DT, ERR_PARAM, ERR_DT_PERIOD = -2, -3, -4, -5, -7, -10


class Exported:
    """One task exported and built, with a fresh native Controller for recording."""

    def __init__(self, name: str, root: Path):
        self.task = vfdsl.load(TASKS_DIR / f"{name}.vf")
        self.directory = root / name
        self.result = export(self.task, self.directory)
        make(self.directory, None if name == DEFAULT_BUILD else TEST_CFLAGS)

    def controller(self):
        return pipeline.build(self.task, backend="native")[0]


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    """name -> Exported, each task exported and built once for the module."""
    built: dict[str, Exported] = {}

    def get(name: str) -> Exported:
        if name not in built:
            built[name] = Exported(name, tmp_path_factory.mktemp("export"))
        return built[name]

    return get


@pytest.fixture(params=TASKS)
def exported(request, exports) -> Exported:
    return exports(request.param)


@pytest.fixture(params=TASKS_WITH_PARAMS)
def exported_with_params(request, exports) -> Exported:
    return exports(request.param)


@pytest.fixture(params=CONTRACT_TASKS)
def contract_task(request, exports) -> Exported:
    return exports(request.param)


@pytest.fixture
def experiment_b(exports) -> Exported:
    return exports("paper_b_virtual_rcm")


def _ticks(name: str) -> int:
    return 2000 if name in EXPERIMENTS else 200


# ------------------------------------------------------------------------------------------- replay
def test_replay_gives_controller_steps_answers(exported):
    ctrl = exported.controller()
    ticks = record(ctrl, _ticks(exported.task.name))
    answers = replay(exported.directory, [t.line() for t in ticks], ticks[0].dt)
    statuses = [status for status, _ in answers]
    assert statuses == [t.status for t in ticks]
    worst = max(float(np.max(np.abs(dq - t.dq), initial=0.0)) for (_, dq), t in zip(answers, ticks))
    assert worst <= 1e-12


def test_replay_says_uncertified_where_controller_step_does(exports):
    """Forty states of polyline_guide 1e-3 rad from its start (random pushes), one after another: most outside the
    fixture, and at some of those phase 2's (B) finds no certificate (least violation, x_A: status 9). The C
    library gives every tick's status as Controller.step() does, the bit UNCERTIFIED included, and the same dq."""
    exported = exports("polyline_guide")
    ctrl = exported.controller()
    robot = Robot.load(exported.task.robots[0].urdf)
    rng = np.random.default_rng(21)
    ticks = []
    for _ in range(40):
        q = np.clip(np.array(exported.task.start) + rng.normal(scale=1e-3, size=robot.nq), robot.lower, robot.upper)
        inputs = {name: rng.normal(scale=2.0, size=size) for name, size in ctrl.input_sizes.items()}
        dq = ctrl.step(q, inputs, dt=0.01)
        ticks.append(Tick(q, np.concatenate(list(inputs.values())), 0.01, int(ctrl.status), dq))
    answers = replay(exported.directory, [t.line() for t in ticks], 0.01)
    statuses = [t.status for t in ticks]
    assert [status for status, _ in answers] == statuses
    assert statuses.count(StepStatus.LEAST_VIOLATION | StepStatus.UNCERTIFIED) > 0
    assert max(float(np.max(np.abs(dq - t.dq))) for (_, dq), t in zip(answers, ticks)) <= 1e-12


def test_replay_with_params_gives_controller_steps_answers(experiment_b, tmp_path):
    """`replay --params FILE` (every param's numbers in declaration order) answers as Controller.step() with the
    same params: experiment B with its pivot moved 0.3 um (within its 1 um tolerance) and its cone axis tilted,
    300 closed-loop ticks."""
    ctrl = experiment_b.controller()
    params = {"pivot": [3e-7, 0.0, 0.290], "axis": [0.02, -0.2, 1.0]}
    ticks = record(ctrl, 300, params=params)
    flat = ctrl._values.params(params)
    (tmp_path / "params.txt").write_text(" ".join(f"{x:.17g}" for x in flat) + "\n")
    answers = replay(experiment_b.directory, [t.line() for t in ticks], ticks[0].dt, tmp_path / "params.txt")
    assert [status for status, _ in answers] == [t.status for t in ticks]
    assert max(float(np.max(np.abs(dq - t.dq))) for (_, dq), t in zip(answers, ticks)) <= 1e-12
    default = record(experiment_b.controller(), 300)
    assert max(float(np.max(np.abs(a.dq - b.dq))) for a, b in zip(ticks, default)) > 1e-9   # the params matter


def test_bad_values_are_refused_with_their_code_and_zero_dq(exported, tmp_path):
    """Python's step() raises, the C step returns the argument's code with dq zeros, replay prints it."""
    ctrl = exported.controller()
    tick = record(ctrl, 1)[0]
    hi = ctrl._values.q_max
    cases = [(_set(tick.q, 0, np.nan), tick.u, tick.dt, ERR_Q_NONFINITE),
             (_set(tick.q, ctrl.nq - 1, -np.inf), tick.u, tick.dt, ERR_Q_NONFINITE)]
    cases += [(_set(tick.q, i, np.nextafter(hi[i], np.inf)), tick.u, tick.dt, ERR_Q_RANGE)
              for i in np.flatnonzero(np.isfinite(hi))[:1]]
    if tick.u.size:
        cases += [(tick.q, _set(tick.u, tick.u.size - 1, np.nan), tick.dt, ERR_INPUT),
                  (tick.q, _set(tick.u, 0, np.inf), tick.dt, ERR_INPUT)]
    cases += [(tick.q, tick.u, dt, ERR_DT) for dt in (0.0, -0.01, np.nan, np.inf)]
    low, high = ctrl._values.dt_min, ctrl._values.dt_max               # the task's range around its period
    cases += [(tick.q, tick.u, float(dt), ERR_DT_PERIOD)
              for dt in (np.nextafter(high, 2.0), 1000 * tick.dt, 2.0, np.nextafter(low, 0.0), tick.dt / 1000)]
    exe = _contract(exported, tmp_path, [])
    for q, u, dt, code in cases:
        with pytest.raises(VfError):
            ctrl.step(q, _inputs(ctrl, u), None, dt)
        line = " ".join(f"{x:.17g}" for x in (*q, *u))
        (answer, message), = replay(exported.directory, [line], dt)
        assert answer == code and message, (code, line, dt)
        assert code != ERR_DT_PERIOD or f"dt {ctrl._values.dt_rule}" in message       # the period and the range
        result = subprocess.run([str(exe), "refuse", repr(dt)], input=line + "\n", capture_output=True, text=True)
        assert result.stdout.split() == [str(code), "1"]            # dq_out zeros
    for dt in (low, high):                                           # the range's ends are accepted
        assert replay(exported.directory, [tick.line()], dt)[0][0] >= 0


def _set(x: np.ndarray, i: int, value: float) -> np.ndarray:
    y = x.copy()
    y[i] = value
    return y


def _inputs(ctrl, u: np.ndarray) -> dict:
    out, at = {}, 0
    for name, size in ctrl.input_sizes.items():
        out[name] = u[at:at + size]
        at += size
    return out


# --------------------------------------------------------------------------------------------- params
def test_param_checks_refuse_what_python_refuses(exported_with_params, tmp_path):
    """Degenerate param vectors (zeros, mm given as metres, NaN, repeated and swapped points, each param alone)
    are refused by the C library exactly when Python refuses them, at the same check."""
    exported = exported_with_params
    task = exported.task
    ctrl = exported.controller()
    slots = [s for s in ctrl.assembled.context.layout.slots.values() if s.size]
    assert slots
    admissible = Admissible(task, Robot.load(task.robots[0].urdf).reach)
    p0 = admissible.layout.defaults
    vectors = [p0.copy(), np.zeros_like(p0), 1000 * p0, -p0]
    for s in slots:
        part = slice(s.offset, s.offset + s.size)
        for change in (lambda x: 0 * x, lambda x: 1000 * x, lambda x: -x, lambda x: x + 1e-3,
                       lambda x: np.full_like(x, np.nan), lambda x: x[::-1].copy(), lambda x: 1e-13 * x):
            v = p0.copy()
            v[part] = change(v[part])
            vectors.append(v)
        if s.size >= 6:       # a line's or plane's direction, a curve's second point on its first
            v = p0.copy()
            v[s.offset + 3:s.offset + 6] = v[s.offset:s.offset + 3] if s.type == "curve" else 0
            vectors.append(v)
    exe = _contract(exported, tmp_path, [])
    text = "\n".join(" ".join(f"{x:.17g}" for x in v) for v in vectors) + "\n"
    out = subprocess.run([str(exe), "params"], input=text, capture_output=True, text=True, check=True).stdout
    refused = 0
    for v, row in zip(vectors, out.splitlines(), strict=True):
        code, check, _ = map(int, row.split())
        params = {s.name: v[s.offset:s.offset + s.size].reshape(-1, 3) if s.type == "curve" else
                  v[s.offset:s.offset + s.size] for s in slots}
        try:
            ctrl.step(task.start, _inputs(ctrl, np.zeros(sum(ctrl.input_sizes.values()))), params, 0.01)
            python_refuses = False
        except VfError:
            python_refuses = True
        assert (code == ERR_PARAM) == python_refuses, v
        if code == ERR_PARAM and np.isfinite(v).all():
            assert check == admissible.margins.first_failure(admissible.function(v)), v
        elif code == ERR_PARAM:
            assert check == -1
        refused += code == ERR_PARAM
    assert refused >= len(slots)


# ----------------------------------------------------------------------------------- the C contract
def _contract(exported: Exported, workdir: Path, flags: list[str], library_flags: str | None = None) -> Path:
    """tests/export_contract.c linked with the exported library (rebuilt in a copy with ``library_flags``)."""
    directory = exported.directory
    if library_flags is not None:
        directory = workdir / "build"
        shutil.copytree(exported.directory, directory)
        subprocess.run(["make", "-s", "clean"], cwd=directory, env=CLEAN_ENV, check=True)
        build(directory, f"lib{exported.result.api}.a", CFLAGS=library_flags)
    exe = workdir / "contract"
    api = exported.result.api
    subprocess.run(["cc", "-O2", "-g", *flags, "-include", str(directory / f"{api}.h"), f"-DAPI={api}",
                    str(CONTRACT), str(directory / f"lib{api}.a"), "-lm", "-pthread", "-o", str(exe)],
                   check=True, capture_output=True, text=True, env=CLEAN_ENV)
    return exe


def built_export(task, directory: Path):
    """``task`` exported into ``directory`` and built with make (the export's own Makefile, a clean environment)."""
    result = export(task, directory)
    make(directory)
    return result


def api_caller(result):
    """call(name, restype=int, *argtypes): the exported library's function ``<api>_<name>`` with its ctypes types."""
    lib = ctypes.CDLL(str(result.directory / f"lib{result.api}.so"))

    def call(name, restype=ctypes.c_int, *argtypes):
        function = getattr(lib, f"{result.api}_{name}")
        function.restype, function.argtypes = restype, list(argtypes) or None
        return function
    return call


def heap_calls(result, lines: list[str], dt: float, workdir: Path) -> tuple[int, int, int]:
    """export_contract.c's count of heap calls (at _new, in the ticks of ``lines``, after them) on ``result``."""
    wrap = "-Wl," + ",".join(f"--wrap={f}" for f in ("malloc", "calloc", "realloc", "free"))
    exe = _contract(type("Exported", (), {"directory": result.directory, "result": result}), workdir,
                    ["-DCOUNT_HEAP", wrap])
    assert len(lines) < 4096                        # export_contract.c's MAX_TICKS
    ticks = [type("Line", (), {"line": lambda self, text=text: text, "dt": dt})() for text in lines]
    at_new, ticked, later = map(int, _run_contract(exe, "alloc", ticks).split())
    return at_new, ticked, later


def _run_contract(exe: Path, mode: str, ticks, env=None) -> str:
    text = "\n".join(t.line() for t in ticks) + "\n"
    result = subprocess.run([str(exe), mode, repr(ticks[0].dt)], input=text, capture_output=True, text=True,
                            env=env)
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout.strip()


@pytest.mark.slow
def test_no_leak_under_address_sanitizer(contract_task, tmp_path):
    exported = contract_task
    exe = _contract(exported, tmp_path, ["-fsanitize=address"], "-O0 -g -fsanitize=address -fno-omit-frame-pointer")
    ticks = record(exported.controller(), 300)
    env = {**CLEAN_ENV, "ASAN_OPTIONS": "detect_leaks=1:halt_on_error=1"}
    assert _run_contract(exe, "leaks", ticks, env) == "ok"


def test_no_heap_call_after_new(contract_task, tmp_path):
    exported = contract_task
    wrap = "-Wl," + ",".join(f"--wrap={f}" for f in ("malloc", "calloc", "realloc", "free"))
    exe = _contract(exported, tmp_path, ["-DCOUNT_HEAP", wrap])
    ctrl = exported.controller()
    ticks = record(ctrl, 300)
    at_new, ticked, params = map(int, _run_contract(exe, "alloc", ticks).split())
    assert at_new > 0
    assert ticked == 0 and params == 0


def test_two_controllers_in_two_threads_answer_as_alone(contract_task, tmp_path):
    exported = contract_task
    exe = _contract(exported, tmp_path, [])
    ticks = record(exported.controller(), 500)
    assert _run_contract(exe, "threads", ticks) == "0"


def test_one_controller_from_two_threads_is_refused_never_mixed(contract_task, tmp_path):
    exported = contract_task
    exe = _contract(exported, tmp_path, [])
    ticks = record(exported.controller(), 1)
    refused, wrong, answered = map(int, _run_contract(exe, "busy", ticks).split())
    assert refused > 0 and answered > 0
    assert wrong == 0


# ------------------------------------------------------------------------------------ the folder itself
def test_the_folder_is_self_contained_and_reexported_identically(experiment_b, tmp_path):
    exported = experiment_b
    again = export(exported.task, tmp_path / "again")
    written = sorted(p.relative_to(exported.directory) for p in exported.result.files)
    assert written == sorted(p.relative_to(again.directory) for p in again.files)
    match, mismatch, errors = filecmp.cmpfiles(exported.directory, again.directory, [str(p) for p in written],
                                               shallow=False)
    assert not mismatch and not errors
    assert (again.directory / "daqp" / "LICENSE").read_text().strip()
    for path in written:
        text = (exported.directory / path).read_text(errors="replace")
        assert "Python.h" not in text and "casadi/" not in text and str(Path.home()) not in text, path


def test_example_and_cmake_build(experiment_b, tmp_path):
    exported = experiment_b
    out = subprocess.run([str(exported.directory / "example")], capture_output=True, text=True, check=True).stdout
    assert "7 joints" in out and "tick 9: status 0" in out and "a NaN joint: q (joint coordinates)" in out
    if shutil.which("cmake") is None:
        pytest.skip("no cmake")
    source = tmp_path / "src"
    shutil.copytree(exported.directory, source, ignore=shutil.ignore_patterns("*.o", "*.a", "*.so", "example",
                                                                             "replay"))
    for argv in (["cmake", "-S", str(source), "-B", str(tmp_path / "build")],
                 ["cmake", "--build", str(tmp_path / "build"), "-j2"]):
        subprocess.run(argv, env=CLEAN_ENV, check=True, capture_output=True)
    api = exported.result.api
    for name in (f"lib{api}.a", f"lib{api}.so", "example", "replay"):
        assert (tmp_path / "build" / name).is_file(), name


def test_cpp_wrapper_compiles_and_steps(experiment_b, tmp_path):
    exported = experiment_b
    if shutil.which("c++") is None:
        pytest.skip("no C++ compiler")
    api = exported.result.api
    program = tmp_path / "owner.cpp"
    program.write_text(f"""#include "{api}.hpp"
#include <cstdio>
#include <utility>
int main() {{
  vfdsl::{api[3:]} a;
  vfdsl::{api[3:]} b(std::move(a));
  double dq[7], tau[3] = {{0, 0, 0.01}};
  int s = b.step({api}_start(), tau, 0.01, dq);
  std::printf("%d %d\\n", s, vfdsl::{api[3:]}::num_joints);
  return a.get() != nullptr;
}}
""")
    subprocess.run(["c++", "-std=c++11", "-Wall", "-Werror", f"-I{exported.directory}", str(program),
                    str(exported.directory / f"lib{api}.a"), "-pthread", "-o", str(tmp_path / "owner")], check=True,
                   capture_output=True, text=True)
    assert subprocess.run([str(tmp_path / "owner")], capture_output=True, text=True, check=True).stdout == "0 7\n"


def test_the_loop_of_docs_embedding_compiles_and_runs(experiment_b, tmp_path):
    """docs/embedding.md's 1 kHz C++ loop, with a robot that executes dq exactly and stops after 200 ticks."""
    if shutil.which("c++") is None:
        pytest.skip("no C++ compiler")
    exported = experiment_b
    doc = (Path(__file__).parent.parent / "docs" / "embedding.md").read_text()
    (tmp_path / "loop.cpp").write_text(doc.split("```cpp\n")[1].split("```")[0])
    (tmp_path / "robot.cpp").write_text("""#include <cstring>
#include "vf_paper_b_virtual_rcm.h"
static double q[7];
static long n = 0;
static bool started = false;
bool read_joints(double* out) {
  if (!started) std::memcpy(q, vf_paper_b_virtual_rcm_start(), sizeof q);
  started = true;
  std::memcpy(out, q, sizeof q);
  return true;
}
bool read_torque(double* tau) { tau[0] = 0; tau[1] = 0; tau[2] = n == 100 ? 0.0 / 0.0 : 0.01; return true; }
void send_joint_increment(const double* dq) { for (int i = 0; i < 7; ++i) q[i] += dq[i]; }
bool stop_requested() { return ++n > 200; }
""")
    subprocess.run(["c++", "-std=c++14", "-O2", "-Wall", "-Werror", f"-I{exported.directory}", "loop.cpp", "robot.cpp",
                    str(exported.directory / f"lib{exported.result.api}.a"), "-pthread", "-o", "loop"],
                   cwd=tmp_path, check=True, capture_output=True, text=True)
    out = subprocess.run([str(tmp_path / "loop")], capture_output=True, text=True, check=True).stdout
    assert out == "200 ticks, 1 refused (last: an input contains NaN or inf), 0 least-violation\n"


# ----------------------------------------------------------------------------------------------- CLI
def test_cli_exports_with_a_self_test(tmp_path, capsys):
    """The self-test builds a copy of the files the export wrote: the user's files in the folder (a FIFO, a link to
    itself, a link to /) are neither read nor copied."""
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / "a_fifo")
    (out / "loop").symlink_to("loop")
    (out / "root").symlink_to("/")
    assert main(["export", str(TASKS_DIR / "lecture_forbidden_half_space.vf"), "-o", str(out),
                 "--self-test", "50"]) == 0
    printed = capsys.readouterr().out
    assert f"exported {api_name('lecture_forbidden_half_space')}" in printed
    assert "50 closed-loop ticks replayed" in printed
    assert not list(out.glob("*.o"))          # the self-test builds a copy


def test_cli_errors_are_clear(tmp_path, capsys, monkeypatch):
    assert main(["export", str(tmp_path / "missing.vf"), "-o", str(tmp_path / "out")]) == 2
    assert "missing.vf" in capsys.readouterr().err
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["export", str(TASKS_DIR / "lecture_stay_near_goal.vf"), "-o", str(blocker)]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert main(["export", str(TASKS_DIR / "lecture_stay_near_goal.vf"), "-o", str(tmp_path / "out"),
                 "--cache", str(blocker)]) == 2
    err = capsys.readouterr().err                      # (the hint named compile's -o only)
    assert f"the build directory {blocker} is not a directory" in err and "export --cache" in err, err
    monkeypatch.setenv("PATH", str(tmp_path))          # no make (nor anything else) on the PATH
    with pytest.raises(VfError, match="make not found"):
        build(tmp_path)


# ------------------------------------------------------------------------------- errors and sizes (C)
def test_error_index_and_check_name_the_last_refusal(experiment_b, tmp_path):
    """Every refusal sets _error_index and _error_check to its own (a wrong param index after a NaN gives the
    index, not the NaN's place); a failed check gives the param it is about; a success resets both to -1; no
    string function returns NULL, _check_meaning(-1) included."""
    exported = experiment_b
    exe = _contract(exported, tmp_path, [])
    tick = record(exported.controller(), 1)[0]
    nan_joint = " ".join(f"{x:.17g}" for x in _set(tick.q, 3, np.nan))
    out = subprocess.run([str(exe), "errors", repr(tick.dt)], input=f"{tick.line()}\n{nan_joint} 0 0 0\n",
                         capture_output=True, text=True, check=True).stdout.splitlines()
    rows = [line.split() for line in out]
    meta = _meta(exported)
    axis = [p["name"] for p in meta["param_layout"]].index("axis")       # the last param, a direction
    zeros = int(rows[4][3])
    assert meta["param_checks"]["param"][zeros] == axis and "axis" in meta["param_checks"]["meaning"][zeros]
    assert rows == [["nan", str(ERR_PARAM), str(axis), "-1"],
                    ["index", "-6", "99", "-1"],
                    ["nan", str(ERR_PARAM), str(axis), "-1"],
                    ["negative", "-6", "-3", "-1"],
                    ["zeros", str(ERR_PARAM), str(axis), str(zeros)],
                    ["null", "-1", "-1", "-1"],
                    ["step", str(tick.status), "-1", "-1"],
                    ["zeros", str(ERR_PARAM), str(axis), str(zeros)],
                    ["q", str(ERR_Q_NONFINITE), "3", "-1"],
                    ["strings", "0"]]


def _meta(exported: Exported) -> dict:
    from vfdsl.export.writer import portable
    return json.loads(pipeline.build(portable(exported.task), backend="native")[1].meta_path.read_text())


def test_the_header_sizes_make_a_too_small_array_a_compile_error(experiment_b, tmp_path):
    """vf_<task>.h's prototypes carry the sizes (VF_<TASK>_NUM_JOINTS, _INPUT_LENGTH, _PARAM_LENGTH): with
    -Werror, C refuses a 2-number q, a 2-number input array or a 3-number dq; C++'s owner refuses them for a C array
    or a std::array (static_assert); the right sizes, a pointer and std::array compile."""
    exported = experiment_b
    api, macro = exported.result.api, exported.result.api.upper()
    owner = f"vfdsl::{api[3:]}"
    c_calls = {"good": "double q[NQ] = {0}, u[NU] = {0}, dq[NQ], p[NP] = {0}; return s(0, q, u, 0.001, dq) + sp(0, p);",
               "short q": "double q[2] = {0}, u[NU] = {0}, dq[NQ]; return s(0, q, u, 0.001, dq);",
               "short inputs": "double q[NQ] = {0}, u[2] = {0}, dq[NQ]; return s(0, q, u, 0.001, dq);",
               "short dq": "double q[NQ] = {0}, u[NU] = {0}, dq[3]; return s(0, q, u, 0.001, dq);",
               "short params": "double p[2] = {0}; return sp(0, p);"}
    cpp_calls = {"good": f"{owner} f; std::array<double, NQ> q{{}}, dq{{}}; double u[NU] = {{0}}, p[NP] = {{0}};"
                         f" std::vector<double> v(NQ); return f.step(q, u, 0.001, dq) + f.step(v.data(), u, 0.001, "
                         "v.data()) + f.set_params(p);",
                 "short q": f"{owner} f; double q[2] = {{0}}, u[NU] = {{0}}, dq[NQ]; return f.step(q, u, 0.001, dq);",
                 "short dq": f"{owner} f; std::array<double, NQ> q{{}}; std::array<double, 3> dq{{}}; "
                             "double u[NU] = {0}; return f.step(q, u, 0.001, dq);",
                 "short inputs": f"{owner} f; double q[NQ] = {{0}}, u[1] = {{0}}, dq[NQ]; "
                                 "return f.step(q, u, 0.001, dq);"}
    defines = [f"-DNQ={macro}_NUM_JOINTS", f"-DNU={macro}_INPUT_LENGTH", f"-DNP={macro}_PARAM_LENGTH",
               f"-Ds={api}_step", f"-Dsp={api}_set_params"]
    for language, compiler, header, calls in (("c", "cc", f"{api}.h", c_calls),
                                              ("c++", "c++", f"{api}.hpp", cpp_calls)):
        if shutil.which(compiler) is None:
            continue
        for name, body in calls.items():
            source = tmp_path / ("caller.c" if language == "c" else "caller.cpp")
            source.write_text(f'#include <array>\n#include <vector>\n#include "{header}"\nint main(void) {{ {body} }}\n'
                              if language == "c++" else f'#include "{header}"\nint main(void) {{ {body} }}\n')
            result = subprocess.run([compiler, "-O2", "-Wall", "-Werror", *defines, f"-I{exported.directory}",
                                     "-c", str(source), "-o", str(tmp_path / "caller.o")],
                                    capture_output=True, text=True, env=CLEAN_ENV)
            assert (result.returncode == 0) == (name == "good"), (language, name, result.stderr[-2000:])
            if name != "good":
                assert "region of size" in result.stderr or "fewer numbers" in result.stderr, result.stderr[-2000:]


def test_readers_and_a_step_of_one_controller_never_overlap(experiment_b, tmp_path):
    """_violations, _error_index and _error_check take the controller's busy flag as _step does: called in the middle
    of steps (from a signal handler, as another thread would, but every time) they return VF_ERR_BUSY (nothing
    read), or the answer alone; never a torn read. Without the flag they read the step's buffers as it writes them."""
    exported = experiment_b
    exe = _contract(exported, tmp_path, [])
    refused, wrong, _ = map(int, _run_contract(exe, "readers", record(exported.controller(), 1)).split())
    assert refused > 0 and wrong == 0


# ----------------------------------------------------------------------------- replay's lines (C)
def test_replay_lines_carry_params_as_a_recording_with_re_registrations(experiment_b):
    """A line may end with every param (q, inputs, params): they are set before its tick and kept, so a recording
    whose pivot is re-registered every 100 ticks replays as Controller.step() ran it; refused params print the
    error and the check's meaning and run no tick; another count of numbers names both accepted counts."""
    exported = experiment_b
    ctrl = exported.controller()

    def params(k: int) -> dict:            # the pivot re-registered within its 1 um tolerance, the axis tilted
        return {"pivot": [1e-7 * (k // 100 % 4), 0.0, 0.290], "axis": [0.01 * (k // 100), -0.2, 1.0]}

    ticks = record(ctrl, 400, params=params)
    assert len(ticks[0].line().split()) == ctrl.nq + ticks[0].u.size + ticks[0].p.size
    answers = replay(exported.directory, [t.line() for t in ticks], ticks[0].dt)
    assert [status for status, _ in answers] == [t.status for t in ticks]
    assert max(float(np.max(np.abs(dq - t.dq))) for (_, dq), t in zip(answers, ticks)) <= 1e-12
    fixed = record(exported.controller(), 400, params=params(0))
    assert max(float(np.max(np.abs(a.dq - b.dq))) for a, b in zip(ticks, fixed)) > 1e-9    # the changes matter
    zero_axis = " ".join(f"{x:.17g}" for x in (*ticks[0].q, *ticks[0].u, 0, 0, 0.29, 0, 0, 0))
    (code, message), (status, dq) = replay(exported.directory, [zero_axis, ticks[0].line()], ticks[0].dt)
    assert code == ERR_PARAM and "'axis' must not be a zero direction" in message
    assert status == ticks[0].status and np.allclose(dq, ticks[0].dq, rtol=0, atol=1e-12)
    result = subprocess.run([str(exported.directory / "replay")], input=" ".join(["0"] * 34) + "\n",
                            capture_output=True, text=True)
    assert result.returncode == 2 and "34 numbers, expected 10 (q, then every input) or 16" in result.stderr


def test_replay_refuses_an_overlong_line_or_a_nul_byte(experiment_b, tmp_path):
    """A line of 65,535 characters is one tick; a longer line, or a NUL byte in a line or in the params file,
    ends the run with exit status 2 and a message, after the ticks before it (never a tick split or cut)."""
    exported = experiment_b
    tick = record(exported.controller(), 1)[0]
    line = tick.line()
    exe = str(exported.directory / "replay")

    def run(text: bytes, *args: str) -> subprocess.CompletedProcess:
        return subprocess.run([exe, "--dt", repr(tick.dt), *args], input=text, capture_output=True)

    longest = run((line.ljust(65535) + "\n").encode())
    assert longest.returncode == 0 and len(longest.stdout.splitlines()) == 1
    for text, message in (((line + "\n" + line.ljust(65536) + "\n").encode(), b"line 2 is longer than the limit"),
                          ((line + "\n" + " 0" * 40000 + "\n").encode(), b"line 2 is longer than the limit"),
                          ((line + "\n" + line + "\0 1 2\n").encode(), b"line 2 holds a NUL byte"),
                          ((line + "\n" + "\0" + line + "\n").encode(), b"line 2 holds a NUL byte")):
        result = run(text)
        assert result.returncode == 2 and message in result.stderr, result.stderr
        assert len(result.stdout.splitlines()) == 1                 # line 1's tick only
    params = tmp_path / "params.txt"
    params.write_bytes(b"0 0 0.29\0 0 0 1\n")
    result = run((line + "\n").encode(), "--params", str(params))
    assert result.returncode == 2 and b"holds a NUL byte" in result.stderr and not result.stdout
    result = run((line + "\n").encode(), "--dt", "0.001s")
    assert result.returncode == 2 and b"not a number of seconds" in result.stderr


# ------------------------------------------------------------------------------- what the folder holds
def _write_as(exported: Exported, directory: Path, **meta) -> Export:
    """write_export of experiment B's generated library into ``directory``, its metadata changed by ``meta``."""
    from vfdsl.codegen.build import daqp_home
    from vfdsl.codegen.daqp_sources import daqp_sources
    from vfdsl.export.writer import portable, write_export
    library = pipeline.build(portable(exported.task), backend="native")[1]
    if meta:
        changed = directory.parent / f"{directory.name}.json"
        changed.write_text(json.dumps({**json.loads(library.meta_path.read_text()), **meta}))
        library = dataclasses.replace(library, meta_path=changed)
    return write_export(library, daqp_sources(daqp_home()), directory)


def test_the_export_does_not_depend_on_how_the_task_path_is_given(experiment_b, tmp_path, monkeypatch):
    """The task given by its absolute path from another folder, or from a copy of tasks/ under a folder named
    'c*/d??' by a relative path, exports the same bytes as tasks/... from the repository (labels and the generated
    tick's name included)."""
    exported = experiment_b
    names = sorted(str(p.relative_to(exported.directory)) for p in exported.result.files)
    odd = tmp_path / "c*" / "d??"
    shutil.copytree(TASKS_DIR, odd / "tasks")
    monkeypatch.chdir(tmp_path / "c*")
    given = {"absolute": TASKS_DIR.resolve() / "paper_b_virtual_rcm.vf",
             "relative, copied": Path("d??/tasks/paper_b_virtual_rcm.vf")}
    for how, path in given.items():
        again = export(vfdsl.load(path), tmp_path / how)
        assert sorted(str(p.relative_to(again.directory)) for p in again.files) == names, how
        match, mismatch, errors = filecmp.cmpfiles(exported.directory, again.directory, names, shallow=False)
        assert not mismatch and not errors, (how, mismatch)
    assert "paper_b_virtual_rcm.vf:" in (tmp_path / "absolute" / f"{exported.result.api}.c").read_text()


def test_a_path_in_a_comment_cannot_end_it(experiment_b, tmp_path):
    """A source path with '*/', '/*', '??/' (a trigraph) or a newline is escaped in the header's comment: the header
    compiles as C and as C++ (trigraphs on) with -Wall -Werror, and holds the path's text."""
    exported = experiment_b
    written = _write_as(exported, tmp_path / "out", file="a*/b/*c??/\nd.vf")
    header = (written.directory / f"{written.api}.h").read_text()
    assert "a*\\/b/\\*c?\\?/\\012d.vf" in header
    _compile_headers(written, tmp_path)


def _compile_headers(written: Export, tmp_path: Path) -> None:
    """vf_<task>.h as C, and .hpp as C++ (its class constructed and stepped), with -Wall -Werror (-trigraphs)."""
    api = written.api
    (tmp_path / "use.c").write_text(f'#include "{api}.h"\nint main(void) {{ return {api}_num_joints(); }}\n')
    (tmp_path / "use.cpp").write_text(f'#include <array>\n#include "{api}.hpp"\nint main() {{\n'
                                      f'  vfdsl::{cpp_class_name(api[3:])} f;\n'
                                      f'  std::array<double, {api.upper()}_NUM_JOINTS> q{{}}, dq{{}};\n'
                                      f'  std::array<double, {api.upper()}_INPUT_LENGTH> u{{}};\n'
                                      f'  return f.step(q, u, 0.001, dq);\n}}\n')
    for compiler, source, flags in (("cc", "use.c", ["-std=c99"]), ("c++", "use.cpp", ["-std=c++11", "-trigraphs"])):
        if shutil.which(compiler):
            result = subprocess.run([compiler, *flags, "-Wall", "-Wextra", "-Werror", f"-I{written.directory}",
                                     "-c", str(tmp_path / source), "-o", str(tmp_path / "use.o")],
                                    capture_output=True, text=True, env=CLEAN_ENV)
            assert result.returncode == 0, (api, source, result.stderr[-3000:])


@pytest.mark.parametrize("name", ["class", "step", "new", "delete", "int", "and", "errno", "NULL", "numbers",
                                  "violations", "get"])
def test_a_task_named_as_a_keyword_gives_a_compiling_cpp_header(experiment_b, tmp_path, name):
    """Task names are any identifier: a C++ keyword, a standard macro or a member of the owner class names the
    class with a '_' appended (vfdsl::class_); the C API keeps vf_<name>."""
    written = _write_as(experiment_b, tmp_path / "out", task=name)
    assert written.api == f"vf_{name}" and cpp_class_name(name) == name + "_"
    _compile_headers(written, tmp_path)
    assert cpp_class_name("paper_b_virtual_rcm") == "paper_b_virtual_rcm"


# ------------------------------------------------------------------------- writing the folder (links)
def test_the_export_never_writes_through_a_link(experiment_b, tmp_path):
    """A link in the folder where the export writes (a file or a subfolder), or a FIFO there, is refused before
    anything is written, and what it points to is untouched; a hard link is replaced (the other name keeps its
    text); the folder itself given as a link is the user's choice and is written."""
    exported = experiment_b
    outside = tmp_path / "outside.txt"
    outside.write_text("the user's file")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    setups = {"Makefile": lambda d: (d / "Makefile").symlink_to(outside),
              "dangling": lambda d: (d / "README.md").symlink_to(tmp_path / "missing"),
              "generated": lambda d: (d / "generated").symlink_to(elsewhere),
              "daqp/include": lambda d: ((d / "daqp").mkdir(), (d / "daqp" / "include").symlink_to(elsewhere)),
              "fifo": lambda d: os.mkfifo(d / "replay.c"),
              "folder": lambda d: (d / "example.c").mkdir()}
    for what, setup in setups.items():
        folder = tmp_path / what.replace("/", "_")
        folder.mkdir()
        setup(folder)
        before = sorted(p.name for p in folder.rglob("*"))
        with pytest.raises(VfError, match="link|not a regular file") as error:
            _write_as(exported, folder)
        assert "nothing was written" in str(error.value) and error.value.hint
        assert sorted(p.name for p in folder.rglob("*")) == before, what
    assert outside.read_text() == "the user's file" and not list(elsewhere.iterdir())
    folder = tmp_path / "hard"
    folder.mkdir()
    os.link(outside, folder / "Makefile")
    written = _write_as(exported, folder)
    assert outside.read_text() == "the user's file"
    assert (folder / "Makefile").read_bytes() == (exported.directory / "Makefile").read_bytes()
    assert not list(folder.rglob(".*.vfdsl-export"))                      # no temporary file left
    (tmp_path / "link_to_folder").symlink_to(elsewhere)
    written = _write_as(exported, tmp_path / "link_to_folder")
    assert len(list(elsewhere.rglob("*.c"))) == sum(p.suffix == ".c" for p in written.files)


def test_a_file_the_export_would_replace_that_is_the_tasks_own_is_refused(tmp_path, capsys):
    """A task file named as a file of the export (Makefile) in the folder it is exported into: refused before
    anything is written, the task as it was."""
    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(TASKS_DIR / "lecture_remote_center.vf", out / "Makefile")
    shutil.copy(TASKS_DIR / "lecture_remote_center.yaml", out / "Makefile.yaml")
    text = (out / "Makefile").read_text()
    assert main(["export", str(out / "Makefile"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"-o {out}: the export's file {out / 'Makefile'} is the task file" in err and "Traceback" not in err, err
    assert (out / "Makefile").read_text() == text and sorted(p.name for p in out.iterdir()) == ["Makefile",
                                                                                               "Makefile.yaml"]


def test_self_test_count_has_a_limit(tmp_path, capsys):
    """--self-test takes 1 to MAX_TICKS ticks: past it (or not a whole number) a usage error, before anything is
    exported; self_test() itself refuses it too."""
    for text in ("1000000000", "1e9", "0", str(MAX_TICKS + 1)):
        with pytest.raises(SystemExit) as exit_:
            main(["export", str(TASKS_DIR / "lecture_stay_near_goal.vf"), "-o", str(tmp_path / "out"),
                  "--self-test", text])
        assert exit_.value.code == 2 and f"from 1 to {MAX_TICKS:,}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    with pytest.raises(VfError, match="1 to 100,000 ticks"):
        check_count(MAX_TICKS + 1)
    assert check_count(MAX_TICKS) == MAX_TICKS


def test_a_task_without_teleop_has_no_readout(exports):
    """_is_teleoperated 0, _teleop VF_ERR_NO_TELEOP (-11), _row_acting 0: the teleoperation calls exist in every
    export and say there is nothing to read."""
    exported = exports(CONTRACT_TASKS[0])
    lib = ctypes.CDLL(str(exported.directory / f"lib{exported.result.api}.so"))
    api = exported.result.api
    getattr(lib, f"{api}_new").restype = ctypes.c_void_p
    for name in ("teleop", "row_acting"):
        getattr(lib, f"{api}_{name}").argtypes = [ctypes.c_void_p, ctypes.c_void_p if name == "teleop" else ctypes.c_int]
    ctrl = getattr(lib, f"{api}_new")()
    buffer = (ctypes.c_double * 16)()
    try:
        assert getattr(lib, f"{api}_is_teleoperated")() == 0
        assert getattr(lib, f"{api}_teleop")(ctrl, buffer) == -11
        assert getattr(lib, f"{api}_row_acting")(ctrl, 0) == 0
    finally:
        getattr(lib, f"{api}_free").argtypes = [ctypes.c_void_p]
        getattr(lib, f"{api}_free")(ctrl)


def test_an_export_that_fails_before_writing_leaves_no_folder(tmp_path, capsys):
    """The folder is made when the files are written: an export refused at its build (a build cache that is a file)
    left an empty folder and its missing parents behind; a folder under a file is refused before the build."""
    (tmp_path / "cache").write_text("a file")
    task = str(TASKS_DIR / "paper_b_virtual_rcm.vf")
    assert main(["export", task, "-o", str(tmp_path / "out" / "vf"), "--cache", str(tmp_path / "cache")]) == 2
    assert "the build directory" in capsys.readouterr().err and not (tmp_path / "out").exists()
    assert main(["export", task, "-o", str(tmp_path / "cache" / "vf")]) == 2
    err = capsys.readouterr().err
    assert f"cannot create the export directory {tmp_path / 'cache' / 'vf'}: {tmp_path / 'cache'} is not a directory" \
        in err, err


def test_an_empty_folder_is_refused_by_the_python_api_too(tmp_path, monkeypatch):
    """`vfdsl export -o ""` is a usage error; export(task, "") wrote into the current directory (Path("") is ".")."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "README.md").write_text("mine")
    with pytest.raises(VfError, match="an empty path names no folder"):
        export(vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf"), "")
    assert (tmp_path / "README.md").read_text() == "mine" and len(list(tmp_path.iterdir())) == 1
