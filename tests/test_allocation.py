"""A generated step allocates no memory: heap calls counted inside the generated C, tick by tick.

tests/alloc_harness.c is linked with the task's generated C and DAQP's static library, with every malloc,
calloc, realloc and free of both wrapped by a counter (ld --wrap). It replays ticks given on stdin: first the
priming evaluation the Controller makes when it loads a library (phase 2 forced), then a walk through
feasible and infeasible states, so that phase 1 (warm-started) and both recovery solves run many times.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl import pipeline
from vfdsl.codegen.build import daqp_home, find_compiler, solver_libraries
from vfdsl.codegen.daqp_sources import daqp_sources
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime import StepStatus

HARNESS = Path(__file__).with_name("alloc_harness.c")


def harness(library, workdir: Path) -> Path:
    exe = workdir / f"{library.c_path.stem}-count"
    wrap = "-Wl," + ",".join(f"--wrap={name}" for name in ("malloc", "calloc", "realloc", "free"))
    subprocess.run([*find_compiler().command, "-O2", f"-DSTEP={library.c_path.stem}",
                    f"-I{daqp_sources(daqp_home()) / 'include'}", str(HARNESS), str(library.c_path),
                    *solver_libraries(find_compiler(), variables(library)), wrap, "-o", str(exe)],
                   check=True, capture_output=True, text=True)
    return exe


def variables(library) -> int:
    """The QP's number of variables (the step's output x)."""
    return json.loads(library.meta_path.read_text())["outputs"][0]["shape"][0]


def replay(exe: Path, ticks: list[np.ndarray]) -> np.ndarray:
    """Rows of (heap calls, return code, status, x...) per tick."""
    text = "\n".join(" ".join(f"{v:.17g}" for v in tick) for tick in ticks) + "\n"
    out = subprocess.run([str(exe)], input=text, check=True, capture_output=True, text=True).stdout
    return np.array([[float(v) for v in line.split()] for line in out.splitlines()])


@pytest.fixture(scope="module")
def task_b():
    return vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")


@pytest.fixture(scope="module")
def built(task_b):
    """The generated Controller of experiment B and its library."""
    return pipeline.build(task_b, backend="native")


@pytest.fixture(scope="module")
def walk(task_b, built):
    """Ticks (q, u, p, dt, recover) as flat vectors: the two priming ticks (recovery forced, then through the
    priority levels, as the Controller primes), then 300 states alternating between near the start (feasible)
    and 1 mm-scale perturbations (the rows conflict: least violation)."""
    ctrl, _ = built
    robot = Robot.load(task_b.robots[0].urdf)
    rng = np.random.default_rng(3)
    p, dt = ctrl.assembled.context.layout.defaults, task_b.scene.period
    ticks = [np.concatenate([task_b.start, np.zeros(3), p, [dt, recover]]) for recover in (1.0, 0.0)]
    for k in range(300):
        spread = 1e-3 if (k // 20) % 2 else 1e-7
        q = np.clip(task_b.start + rng.normal(scale=spread, size=robot.nq), robot.lower, robot.upper)
        ticks.append(np.concatenate([q, rng.normal(scale=0.02, size=3), p, [dt, 0.0]]))
    return ticks


def test_steps_allocate_nothing_after_the_priming_tick(built, walk, tmp_path):
    ctrl, library = built
    rows = replay(harness(library, tmp_path), walk)
    calls, codes, statuses, xs = rows[:, 0], rows[:, 1], rows[:, 2].astype(int), rows[:, 3:]
    assert not codes.any()
    assert calls[0] > 0                      # the priming tick sets up every DAQP workspace (recovery, retry)
    assert not calls[2:].any(), f"heap calls on ticks {np.flatnonzero(calls[2:]) + 2}"
    assert (statuses[2:] == StepStatus.OPTIMAL).sum() > 50
    assert (statuses[2:] & StepStatus.LEAST_VIOLATION).sum() > 50
    # The harness runs what the Controller runs (built with other compiler flags: recovery answers, which
    # are solved less precisely, are compared by status only; docs/runtime.md).
    for tick, status, x in zip(walk[1:], statuses[1:], xs[1:], strict=True):
        dq = ctrl.step(tick[:ctrl.nq], {"tau": tick[ctrl.nq:ctrl.nq + 3]})
        assert ctrl.status == status
        if status == StepStatus.OPTIMAL:
            np.testing.assert_allclose(dq, x[:ctrl.nq], atol=1e-9)

