"""A bounded tick (issue 35, item 3): every DAQP solve stops after vfdsl.codegen.solve_plan.ITER_LIMIT iterations on
both paths, and a solve that reaches the limit fails like any failed solve: the tick goes on to its next answer
(least violation, then the rest motion) and dq stays finite and inside the joint box. Here the limit is lowered so
that every solve reaches it."""

from __future__ import annotations

import numpy as np
import pytest

import vfdsl
from vfdsl.codegen import solve_plan
from vfdsl.runtime.daqp_solve import solve_daqp
from vfdsl.runtime.qp import StepStatus

from conftest import TASKS_DIR


def test_the_python_solve_stops_at_the_limit(monkeypatch):
    """A QP DAQP needs 3 iterations for (two bounds and a row to add): at a limit of 2 it reports -4, its answer NaN
    to the caller's check."""
    H, g = np.eye(2), np.array([-3.0, -3.0])
    A, lower, upper = np.array([[1.0, 1.0]]), np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    x, flag, iterations, _ = solve_daqp(H, g, A, lower, upper, 1e-9)
    assert flag == 1 and iterations >= 2 and np.allclose(x, [0.5, 0.5])
    monkeypatch.setattr(solve_plan, "ITER_LIMIT", iterations - 1)
    assert solve_daqp(H, g, A, lower, upper, 1e-9)[1] == -4


@pytest.mark.parametrize("backend", ["interpreted", "native"])
@pytest.mark.parametrize("name", ["keep_out", "paper_b_virtual_rcm"])
def test_ticks_whose_solves_reach_the_limit_stay_safe(monkeypatch, tmp_path, backend, name):
    """The limit at 1: DAQP can finish no solve (a plain QP fails, -4; with priority levels it stops at a point of
    the hard rows, its exit 3, which the levels' exact solve then finishes where it can certify it). Pushed hard in
    random directions for 30 ticks from the start and then from states outside the fixture: every dq is finite and
    inside the joint box, and a tick that reports OPTIMAL holds every hard row."""
    monkeypatch.setattr(solve_plan, "ITER_LIMIT", 1)
    task = vfdsl.load(TASKS_DIR / f"{name}.vf")
    ctrl = vfdsl.compile(task, backend=backend, cache_dir=tmp_path)
    if backend == "native":           # the generated C was built with the lowered limit
        sources = [p.read_text() for p in tmp_path.glob("*/*.c") if not p.name.startswith("vfmesh")]
        assert sources and all("settings->iter_limit = 1;" in text for text in sources)
    rng = np.random.default_rng(3)
    q = np.array(task.start, dtype=float)
    for k in range(30):
        if k == 15:
            q = q + rng.normal(scale=0.02, size=q.size)           # outside the fixture: least-violation ticks
        inputs = {n: rng.normal(scale=5.0, size=size) for n, size in ctrl.input_sizes.items()}
        qp = ctrl.problem(q, inputs)
        dq = ctrl.step(q, inputs)
        assert np.all(np.isfinite(dq))
        lower, upper = qp.lb[:ctrl.nq], qp.ub[:ctrl.nq]
        clipped = StepStatus.BOUNDS_CLIPPED in ctrl.status
        assert clipped or np.all((dq >= lower - 1e-9) & (dq <= upper + 1e-9))
        if ctrl.status == StepStatus.OPTIMAL:
            assert not [v for v in ctrl.violations() if not v.label.soft]
        q = q + dq
