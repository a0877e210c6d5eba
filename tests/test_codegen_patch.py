"""The patch of CasADi's generated C (vfdsl.codegen.patch) against golden files, byte for byte.

tests/golden/casadi-<version>/ holds, for a small two-level step, the C that CasADi <version> generates
(``<name>.casadi.c``) and its patched form (``<name>.patched.c``), the C files the patch inserts (daqp_persistent.c,
memory_slots.c) stood in for by short markers, so that the golden files change only with CasADi or the patch. A new
CasADi: run ``python
tests/test_codegen_patch.py``, which writes the files for the installed version, and review the patched output
against the previous version's before committing it.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import casadi as ca
import pytest

from vfdsl.codegen.build import casadi_c
from vfdsl.codegen import patch
from vfdsl.codegen.solve_plan import PlannedFunction, SolvePlan, plans_of
from vfdsl.errors import VfError
from vfdsl.runtime import build_step_function

GOLDEN = Path(__file__).parent / "golden" / f"casadi-{ca.__version__}"
PREFIX = "vf_golden"
STEPS = ("one_level", "two_levels")


def golden_step(name: str) -> PlannedFunction:
    """A 2-joint tick with one row x0 + x1 <= p; ``two_levels``: and a priority level x0 = u0 above the damping."""
    q, u, p, dt = ca.SX.sym("q", 2), ca.SX.sym("u", 2), ca.SX.sym("p", 1), ca.SX.sym("dt")
    data = [ca.SX.eye(2) + 0.1 * ca.diag(ca.cos(q)), -u, ca.DM([[1, 1]]), -ca.inf, p,
            -10 * dt * ca.DM.ones(2), 10 * dt * ca.DM.ones(2)]
    if name == "two_levels":
        data += [ca.DM([[1, 0]]), u[0], ca.SX.eye(2), ca.SX.zeros(2)]
    qp_data = ca.Function("qp", [q, u, p, dt], data, ["q", "u", "p", "dt"],
                          ["H", "g", "A", "lba", "uba", "lbx", "ubx", *(f"level{i}" for i in range(len(data) - 7))])
    return build_step_function(qp_data, PREFIX, native=True)


STAND_INS = {"PERSISTENT_DAQP": "/* golden: daqp_persistent.c */\n",
             "MEMORY_SLOTS": "/* golden: memory_slots.c of @PREFIX@ */\n@INIT_SLOT@\n@FREE_SLOT@\n"}


@pytest.fixture(autouse=True)
def stand_ins(monkeypatch):
    for name, text in STAND_INS.items():
        monkeypatch.setattr(patch, name, text)


def patched(source: str, name: str, plans=None) -> str:
    return patch.patch_generated_c(source, PREFIX, plans_of(golden_step(name)) if plans is None else plans)


def generated(name: str) -> str:
    checks = ca.Function("checks", [ca.SX.sym("p", 1)], [ca.SX.zeros(0, 1)])
    with tempfile.TemporaryDirectory() as work:
        return casadi_c(golden_step(name), PREFIX, Path(work), checks)[0]


def golden(name: str, kind: str) -> str:
    path = GOLDEN / f"{name}.{kind}.c"
    if not path.is_file():
        pytest.fail(f"no golden files for CasADi {ca.__version__} (the patch was made on the versions in "
                    f"{GOLDEN.parent}): run python tests/test_codegen_patch.py and review its patched output")
    return path.read_text()


@pytest.mark.parametrize("name", STEPS)
def test_casadi_generates_the_golden_input(name):
    assert generated(name) == golden(name, "casadi"), (
        f"CasADi {ca.__version__} no longer generates {GOLDEN / name}.casadi.c: check that vfdsl.codegen.patch's "
        "patterns still match its output, then regenerate the golden files (python tests/test_codegen_patch.py)")


@pytest.mark.parametrize("name", STEPS)
def test_the_patch_gives_the_golden_output(name):
    assert patched(golden(name, "casadi"), name) == golden(name, "patched"), (
        f"the patched C differs from {GOLDEN / name}.patched.c")


def test_the_plans_are_typed_and_the_names_hold_no_data():
    plans = plans_of(golden_step("two_levels"))
    assert set(plans) == {"phase1_try0", "phase1_try1", "phase1_try2", "phase2a", "phase2a_again", "phase2b"}
    assert plans["phase1_try2"] == SolvePlan(False, (5, 6, 8), 1e-6, partial=True, exact=True)
    assert plans["phase2a"] == plans["phase2a_again"] == SolvePlan()
    assert plans["phase2b"] == SolvePlan(break_points=(5, 6, 8), exact=True, start=True)
    assert plans_of(golden_step("one_level"))["phase1_warm"] == SolvePlan(warm_start=True)
    assert plans_of(golden_step("one_level"))["phase2b"] == SolvePlan(break_points=(5,), exact=True, start=True)
    output = golden("two_levels", "patched")
    assert "{3, 1e-6, 1, 1, 0, {5, 6, 8}}" in output and "{3, 1e-8, 0, 1, 0, {5, 6, 8}}" in output
    assert "{3, 0.0, 0, 1, 1, {5, 6, 8}}" in output


def test_a_rho_other_than_a_power_of_ten_reaches_the_c_exactly():
    source = golden("two_levels", "casadi")
    plans = dict(plans_of(golden_step("two_levels")))
    plans["phase1_try0"] = SolvePlan(False, (5, 6, 8), 0.1 + 0.2, exact=True)
    assert "{3, 0.30000000000000004, 0, 1, 0, {5, 6, 8}}" in patched(source, "two_levels", plans)


def test_a_conic_without_a_plan_is_refused():
    plans = dict(plans_of(golden_step("one_level")))
    del plans["phase2a"]
    with pytest.raises(VfError, match="conic 'phase2a' that has no solve plan"):
        patched(golden("one_level", "casadi"), "one_level", plans)


def test_a_one_variable_conic_gets_its_plan():
    """A step of one variable: CasADi names its 1 x 1 Hessian "h", not "h[1x1]", in a conic's comment, where the patch
    looked for "h[": those conics kept CasADi's plain DAQP call without their plans (phase 2's (B) not solved from
    x_A, its certificate output the cost: a least-violation tick's status 1.04 in the generated C, 1 interpreted)."""
    q, u, p, dt = ca.SX.sym("q", 1), ca.SX.sym("u", 1), ca.SX.sym("p", 1), ca.SX.sym("dt")
    qp_data = ca.Function("qp", [q, u, p, dt], [ca.SX.eye(1), -u, ca.DM([[1]]), -ca.inf, p,
                                                 -10 * dt * ca.DM.ones(1), 10 * dt * ca.DM.ones(1)])
    step = build_step_function(qp_data, PREFIX, native=True)
    checks = ca.Function("checks", [ca.SX.sym("p", 1)], [ca.SX.zeros(0, 1)])
    with tempfile.TemporaryDirectory() as work:
        source = casadi_c(step, PREFIX, Path(work), checks)[0]
    assert "/* phase2b:(h," in source
    output = patch.patch_generated_c(source, PREFIX, plans_of(step))
    assert "casadi_daqp_solve(d, arg, res, iw, w);" not in output


@pytest.mark.parametrize("edit, message", [
    (("#include <math.h>\n", ""), "no single <math.h>"),
    (("void casadi_daqp_free_mem(struct casadi_daqp_data* d) {\n}\n", ""), "a DAQP interface this vfdsl does not"),
    (("  int bnb_itercount;\n};\n", "};\n"), "DAQP data this vfdsl does not know"),
    (("#ifndef CASADI_MAX_NUM_THREADS\n", "#ifndef CASADI_THREADS\n"), "an entry point this vfdsl does not know"),
])
def test_a_casadi_output_that_no_longer_matches_is_refused(edit, message):
    source = golden("one_level", "casadi")
    assert edit[0] in source
    with pytest.raises(VfError, match=message):
        patched(source.replace(*edit), "one_level")


if __name__ == "__main__":      # write the golden files for the installed CasADi
    GOLDEN.mkdir(parents=True, exist_ok=True)
    for name, text in STAND_INS.items():
        setattr(patch, name, text)
    for step in STEPS:
        source = generated(step)
        (GOLDEN / f"{step}.casadi.c").write_text(source)
        (GOLDEN / f"{step}.patched.c").write_text(patched(source, step))
        print(f"wrote {GOLDEN / step}.casadi.c and .patched.c", file=sys.stderr)
