"""The feasibility and agreement figures docs/runtime.md states (its table "Feasibility and agreement, measured") hold
on a short run of paper A's and paper B's simulations, measured as benchmarks/feasibility.py measures them: the
excess of a tick's rows and bounds over their bounds on ticks reported OPTIMAL (both paths), and how far the
generated and interpreted answers differ. The stated row bounds are the solver's acceptance tolerances."""

from __future__ import annotations

import importlib.util
import re
import sys

import pytest
from conftest import DOCS_DIR, REPO

import vfdsl
from vfdsl.errors import VfError
from vfdsl.passes.clause_ranges import LEVELS_TOLERANCE
from vfdsl.pipeline import FEASIBILITY_TOLERANCE

TASKS = REPO / "tasks"
ROW = re.compile(r"^\| ([^|]+?) \| ([0-9.]+e-[0-9]+) \|", re.MULTILINE)


def _stated() -> dict[str, float]:
    """figure -> its stated bound, from the table under the heading "Feasibility and agreement, measured"."""
    text = (DOCS_DIR / "runtime.md").read_text()
    section = text.split("### Feasibility and agreement, measured", 1)[1].split("\n#", 1)[0]
    return {name: float(bound) for name, bound in ROW.findall(section)}


def _measure():
    spec = importlib.util.spec_from_file_location("vfdsl_bench_feasibility", REPO / "benchmarks" / "feasibility.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module             # (its dataclass looks its module up there)
    spec.loader.exec_module(module)
    return module.measure


@pytest.fixture(scope="module")
def measured() -> dict:
    """One trial of paper A's scene (160 ticks) and 3 s of paper B's (300 ticks)."""
    measure = _measure()
    return {"A": measure(TASKS / "paper_a_follow_curve.vf", TASKS / "paper_a_follow_curve.sim.yaml", trials=1),
            "B": measure(TASKS / "paper_b_virtual_rcm.vf", TASKS / "paper_b_virtual_rcm.sim.yaml", trials=1,
                         duration=3.0)}


def test_the_stated_row_bounds_are_the_solver_acceptance_tolerances():
    stated = _stated()
    assert stated["rows and bounds, tick reported OPTIMAL, one level"] == FEASIBILITY_TOLERANCE
    assert stated["rows and bounds, tick reported OPTIMAL, priority levels"] == LEVELS_TOLERANCE


def test_optimal_ticks_hold_their_rows_within_the_stated_bound(measured):
    """Both tasks have priority levels (damping is their third); every tick of both runs is OPTIMAL on both paths."""
    bound = _stated()["rows and bounds, tick reported OPTIMAL, priority levels"]
    for name, f in measured.items():
        for path in ("native", "interpreted"):
            assert f.optimal[path] == f.ticks > 0, (name, path)
            assert f.all_excess[path] <= bound, (name, path, f.all_excess[path])


def test_the_paths_agree_within_the_stated_figures(measured):
    stated = _stated()
    assert measured["B"].dq_diff <= stated["generated - interpreted dq, paper B"], measured["B"].dq_diff
    assert measured["A"].dq_diff <= stated["generated - interpreted dq, paper A"], measured["A"].dq_diff
    for name, f in measured.items():
        assert f.cost_diff <= stated["a priority level's cost, generated - interpreted"], (name, f.cost_diff)


def test_a_tolerance_below_the_solver_names_what_rows_hold_to_with_priority_levels(tmp_path):
    path = tmp_path / "t.vf"
    path.write_text('task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
                    "require tip stays_at([0, 0, 290]) within 1e-12\n")
    with pytest.raises(VfError) as caught:
        vfdsl.load(path)
    message = caught.value.message
    assert f"{FEASIBILITY_TOLERANCE * 1e3:g} mm" in message
    assert f"{LEVELS_TOLERANCE * 1e3:g} mm with priority levels" in message
