"""The tick's buffers are declared once (vfdsl.codegen.tick_buffers), and everything that names them follows.

For experiment B, compiled and exported: the step Function's arguments and results (names and lengths) are the
declared ones at the task's sizes; the generated header declares them as a C compiler reads them (a probe program
prints the slots, names and lengths of ``VFDSL_BUFFERS``), in the library and in the exported folder alike; the
runners' arrays have the declared lengths; and the C that reads the buffers (checked_step.h, stepper.c, the
export's api.c and replay.c) holds no hand-written list of them.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl import pipeline
from vfdsl.codegen.build import CHECKED_STEP, STEPPER
from vfdsl.codegen.tick_buffers import ARGUMENTS, BUFFERS, DATA_ARGUMENTS, RESULTS, Slot, c_call, lengths, step_lengths
from vfdsl.compiler.assemble import assemble
from vfdsl.export import export
from vfdsl.export.writer import TEMPLATES
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import build_step_function

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")

TASK = TASKS_DIR / "paper_b_virtual_rcm.vf"
PROBE = """#include <stdio.h>
#define PRINT(slot, name, length) printf("%d %s %ld\\n", (int) slot, #name, (long) (length));
int main(void) {
  printf("%d %d\\n", (int) VFDSL_N_ARGS, (int) VFDSL_N_BUFFERS);
  VFDSL_BUFFERS(PRINT)
  return 0;
}
"""


@pytest.fixture(scope="module")
def compiled():
    """(controller, library, metadata) of experiment B on the native path."""
    ctrl, library = pipeline.build(vfdsl.load(TASK), backend="native")
    return ctrl, library, json.loads(library.meta_path.read_text())


def _task_lengths(meta: dict) -> tuple[int, ...]:
    """The declared lengths at the task's sizes, as the metadata states them."""
    nq, slack = meta["variables"]["dq"], meta["variables"]["slack"]
    return lengths(nq=nq, nu=sum(i["size"] for i in meta["input_layout"]), np=len(meta["default_params"]),
                   nx=nq + slack, rows=len(meta["rows"]))


def _probe(header: Path, work: Path) -> list[tuple[int, str, int]]:
    """(slot, name, length) of each buffer as the C compiler reads ``header``, after (VFDSL_N_ARGS, N_BUFFERS)."""
    (work / "probe.c").write_text(PROBE)
    subprocess.run(["cc", "-include", str(header), "probe.c", "-o", "probe"], cwd=work, check=True,
                   capture_output=True)
    lines = subprocess.run([str(work / "probe")], check=True, capture_output=True, text=True).stdout.splitlines()
    assert lines[0].split() == [str(len(ARGUMENTS)), str(len(BUFFERS))]
    return [(int(k), name, int(n)) for k, name, n in (line.split() for line in lines[1:])]


def _declared(meta: dict) -> list[tuple[int, str, int]]:
    return [(int(Slot[b.name.upper()]), b.name, n) for b, n in zip(BUFFERS, _task_lengths(meta), strict=True)]


def test_the_step_function_has_the_declared_buffers(compiled):
    _, _, meta = compiled
    task = vfdsl.load(TASK)
    problem = assemble(task, Robot.load(task.robots[0].urdf))
    assert tuple(problem.function.name_in()) == DATA_ARGUMENTS
    for native in (False, True):
        step = build_step_function(problem.function, "vf_buffers", row_groups=problem.row_groups, native=native)
        assert step_lengths(step) == _task_lengths(meta)
    recorded = [(io["name"], io["shape"][0] * io["shape"][1]) for io in (*meta["inputs"], *meta["outputs"])]
    assert recorded == list(zip((*ARGUMENTS, *RESULTS), _task_lengths(meta), strict=True))   # the compiled step


def test_the_generated_header_declares_them_as_the_compiler_reads_them(compiled, tmp_path):
    _, library, meta = compiled
    assert _probe(library.h_path, tmp_path) == _declared(meta)
    assert c_call() in library.h_path.read_text()       # the calling contract's arg/res line
    assert c_call() == "arg = {q, u, p, &dt, &recover}, res = {x, &status, violation}"


def test_the_runners_arrays_have_the_declared_lengths(compiled):
    ctrl, _, meta = compiled
    expected = _task_lengths(meta)
    runner = ctrl._runner
    assert (runner.x.size, runner.status.size, runner.violation.size) == tuple(
        expected[slot] for slot in (Slot.X, Slot.STATUS, Slot.VIOLATION))


def test_the_export_uses_the_same_declarations(compiled, tmp_path):
    _, _, meta = compiled
    exported = export(vfdsl.load(TASK), tmp_path / "out")
    header = next((exported.directory / "generated").glob("vf_*.h"))      # the generated tick's header
    assert _probe(header, tmp_path) == _declared(meta)
    api = exported.directory / f"{exported.api}.c"
    assert "VFDSL_BUFFERS(" in api.read_text()
    subprocess.run(["cc", "-fsyntax-only", "-Igenerated", "-Idaqp/include", api.name], cwd=exported.directory,
                   check=True, capture_output=True)


def _copies(text: str) -> list[str]:
    """Hand-written lists of the buffers in C ``text``: in its code (comments and strings left out: a function's
    documented signature may name its arguments), three declared names in a row, as names (fields, variables) or
    as their slots VFDSL_<NAME>, or the sizes NQ, NU, NP in a row; in its strings, every buffer's name in order."""
    names = [b.name for b in BUFFERS]
    text = re.sub(r"/\*.*?\*/|//[^\n]*", " ", text, flags=re.S)
    found = [s for s in re.findall(r'"(?:[^"\\\n]|\\.)*"', text) if ", ".join(names) in s]
    code = re.sub(r'"(?:[^"\\\n]|\\.)*"', '""', text)
    for window in zip(names, names[1:], names[2:]):
        for spelled in (window, [f"VFDSL_{name.upper()}" for name in window]):
            found += re.findall(r"\b" + r"(?:\[[^]]*\])?[\s,]+".join(spelled) + r"\b", code)
    return found + re.findall(r"\bNQ[\s,]+NU[\s,]+NP\b", code)


@pytest.mark.parametrize("path", [CHECKED_STEP, STEPPER, TEMPLATES / "api.c", TEMPLATES / "replay.c"],
                         ids=lambda p: p.name)
def test_the_c_that_reads_the_buffers_holds_no_copy_of_them(path):
    assert _copies(path.read_text()) == []


def test_a_copy_would_be_found():
    assert _copies("enum { VFDSL_Q, VFDSL_U, VFDSL_P };") and _copies("long size[] = {NQ, NU, NP, 1};")
    assert _copies(f'"{", ".join(b.name for b in BUFFERS)}"') and _copies("double x[9], status[1], violation[4];")
    assert not _copies("/* q, u, p */") and not _copies('"run(q, u, p, dt, recover)"')
