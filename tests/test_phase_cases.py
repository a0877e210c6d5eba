"""A procedure's step: one case per steady phase and one for blends (vfdsl.compiler.cases,
vfdsl.runtime.qp.build_procedure_step). A phase's case keeps the rows held in every phase, its hard rows and the soft
rows; the rows it leaves out are exactly those whose bounds are infinite in that phase, the terms it leaves out
exactly those that weigh 0 there (a steady phase whose only term is damping solves a plain QP); the activity picks the
right case; and the step made of the cases answers as the one QP of every phase's rows and terms (the assembled
qp_data through build_step_function, a second evaluation), at random states in each phase, steady and blending,
least-violation ticks included (there, the same violations). The interpreted path evaluates both; the generated C is
held to the interpreted path by tests/test_procedure_native.py and tests/test_export_procedure.py."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import vfdsl
from vfdsl.compiler.cases import case_index, phase_cases
from vfdsl.pipeline import FEASIBILITY_TOLERANCE
from vfdsl.runtime.native import BufferedFunction
from vfdsl.runtime.qp import StepStatus, build_procedure_step, build_step_function

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "tasks" / "procedures" / "needle_procedure.vf"
SOFT_PHASES = """\
task soft_phases
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
frame needle = tip axis [0, 0, -1]
input f : force
input go : button
param far : point = [100, 100, 100]
monitor pressed = go
use joint_safety()
require tip above(plane([0, 0, -500], [0, 0, 1]))
phase a initial { minimize track(tip, f, gain = 1 mm/s/N) }
phase b { require tip stays_at(far) within 1 mm soft weight 10
          minimize track(tip, f, gain = 2 mm/s/N) }
phase c final { require needle keeps_direction([0, 0, -1]) within 2 deg
                require tip stays_at(far) within 0.5 mm }
transition a -> b when pressed
transition b -> c when pressed
blend 100 ms
"""
"""Rows held in every phase (above), a phase with a soft fixture (b) and one whose hard fixtures are far off (c)."""
SAME = 1e-8
"""The two answers agree to the solver's tolerance (relative to 1 + |x|): they are the same QP's, but where the levels'
exact solve gives no certificate each is DAQP's own answer (primal tolerance 1e-10 per row, vfdsl.runtime.qp), and
DAQP's iterations differ between the QP with the idle phases' rows (bounds infinite) and the case without them
(measured: up to 1.7e-9 at these states). At a least-violation tick the violations agree (the least violation is
unique), the motions to 2.5e-5 only: phase 2's motion within the least-violation set weighs the held rows by the
longest row of the QP (vfdsl.runtime.qp._least_violation), which the idle phases' rows lengthen in the one QP; that
motion is not yet unique across such scalings (the open issue on exact levels at least-violation ticks)."""


def soft_phases(tmp_path):
    path = tmp_path / "soft_phases.vf"
    path.write_text(SOFT_PHASES.replace("use joint_safety()\n", 'import "library/fixtures.vf"\nuse joint_safety()\n'))
    (tmp_path / "library").symlink_to(REPO / "tasks" / "library")
    return vfdsl.load(path)


def cases_of(task):
    ctrl = vfdsl.compile(task, backend="interpreted")
    return task, ctrl.assembled, phase_cases(ctrl.assembled, task)


@pytest.fixture(scope="module")
def example():
    return cases_of(vfdsl.load(EXAMPLE))


@pytest.fixture(scope="module", params=["example", "soft_phases"])
def procedure(request, tmp_path_factory):
    if request.param == "example":
        return request.getfixturevalue("example")
    return cases_of(soft_phases(tmp_path_factory.mktemp("cases")))


def random_arguments(rng, task, problem, activity):
    """(q, u, p, dt, activity) at a random state near the task's start (0 when it has none; some far from it),
    random inputs and the full params' defaults with random captures."""
    ctx = problem.context
    start = np.zeros(ctx.nq) if task.start is None else np.array(task.start, dtype=float)
    q = start + rng.normal(scale=rng.choice([0.01, 0.3]), size=ctx.nq)
    u = rng.normal(scale=3.0, size=ctx.u.numel())
    p = np.array(ctx.layout.defaults, dtype=float)
    for slot in ctx.layout.capture_slots.values():
        value = rng.normal(scale=0.05, size=slot.size)
        p[slot.offset:slot.offset + slot.size] = value / np.linalg.norm(value) if slot.type == "direction" else value
    return [q, u, p, 0.001, activity]


def activities(rng, task, n_widths: int):
    """(k, activity): per phase k its steady activity, then a blend into it from another phase (weights split,
    funnel widths random)."""
    n = len(task.phases)
    for k in range(n):
        a = np.zeros(2 * n + n_widths)
        a[k] = a[n + k] = 1.0
        yield k, a
        b = a.copy()
        s = rng.uniform(0.1, 0.9)
        b[k], b[(k + 1 + int(rng.integers(n - 1))) % n] = s, 1.0 - s
        b[2 * n:] = rng.uniform(0, 2e-3, n_widths)
        yield k, b


def same(a, b) -> bool:
    """a and b equal to rounding (relative to their largest finite entry), infinite entries equal."""
    if a.shape != b.shape or not np.array_equal(np.isinf(a), np.isinf(b)) or np.any(a[np.isinf(a)] != b[np.isinf(b)]):
        return False
    finite = np.isfinite(b)
    scale = max(1.0, np.max(np.abs(b[finite]), initial=0.0))
    return bool(np.max(np.abs(a[finite] - b[finite]), initial=0.0) <= 1e-14 * scale)


def nonzero_levels(outputs):
    """qp_data's levels (R_j, r_j) without the rows that are zero with a zero target, the empty ones left out."""
    return [(R[keep], r[keep]) for R, r in zip(outputs[7::2], outputs[8::2])
            for keep in [np.any(R != 0, axis=1) | (r.ravel() != 0)] if keep.any()]


def case_of(cases, task, k, activity):
    """The case the step picks for ``activity`` (case_index), checked: phase k's steady one, or the blending one."""
    case = cases[int(case_index(ca.DM(activity), len(task.phases)))]
    steady = activity[k] == 1.0
    assert case.steady == steady and case.phase == (task.phases[k].name if steady else None)
    return case


def test_each_case_keeps_the_rows_of_every_phase_its_own_and_the_soft_ones(procedure):
    task, problem, cases = procedure
    for case in cases[:-1]:
        kept = [problem.row_labels[i] for i in case.rows]
        assert {label.phase for label in kept if not label.soft} <= {None, case.phase}
        left_out = set(range(len(problem.row_labels))) - set(case.rows)
        assert all(problem.row_labels[i].phase not in (None, case.phase) and not problem.row_labels[i].soft
                   for i in left_out)
        assert list(case.rows) == sorted(case.rows)
    assert set().union(*(c.rows for c in cases[:-1])) == set(range(len(problem.row_labels)))
    assert cases[-1].rows == tuple(range(len(problem.row_labels)))


def test_a_case_is_the_whole_qp_without_its_unbounded_rows_and_zero_terms(procedure):
    task, problem, cases = procedure
    rng = np.random.default_rng(3)
    n = len(task.phases)
    widths = problem.function.numel_in(4) - 2 * n
    out = problem.function.index_out
    for k, activity in activities(rng, task, widths):
        args = random_arguments(rng, task, problem, activity)
        whole = [np.array(v) for v in problem.function(*args)]
        case = case_of(cases, task, k, activity)
        part = [np.array(v) for v in case.function(*args)]
        left_out = sorted(set(range(len(problem.row_labels))) - set(case.rows))
        assert np.all(whole[out("lba")][left_out] == -np.inf) and np.all(whole[out("uba")][left_out] == np.inf)
        for name in ("A", "lba", "uba"):
            assert np.array_equal(part[out(name)], whole[out(name)][list(case.rows)])
        assert np.all(np.isfinite(part[out("A")]))
        for name in ("H", "g", "lbx", "ubx"):          # (the zero terms substituted: sums in another order)
            assert same(part[out(name)], whole[out(name)])
        levels, levels_case = nonzero_levels(whole), nonzero_levels(part)
        if len(part) == 7:
            assert len(levels) <= 1                      # one level or none: a plain QP
        else:
            assert len(levels_case) == len(levels)
            for (R, r), (R_case, r_case) in zip(levels, levels_case):
                assert same(R, R_case) and same(r, r_case)


def test_a_phase_whose_only_term_is_damping_solves_one_plain_qp_when_steady(example):
    task, problem, cases = example
    steady = {c.phase: c for c in cases if c.steady}
    assert steady["done"].function.n_out() == 7 and steady["hold"].function.n_out() == 7
    assert steady["insert"].function.n_out() == 7 + 2 * 3                   # track's two parts, damping
    assert steady["insert"].function.size1_out(7) == 3                       # insert's track alone
    assert len(cases) == len(task.phases) + 1 and cases[-1].function is problem.function   # blending: every row


def test_the_step_of_cases_answers_as_the_one_qp(procedure):
    task, problem, cases = procedure
    options = dict(row_groups=problem.row_groups, feas_tol=FEASIBILITY_TOLERANCE, native=False,
                   last_level_is_cost=problem.last_level_is_damping)
    one = BufferedFunction.interpreted(build_step_function(problem.function, "one_qp", **options))
    options.pop("last_level_is_cost")
    per_phase = BufferedFunction.interpreted(build_procedure_step(
        [(c.function, c.rows, c.last_level_is_damping) for c in cases],
        lambda activity: case_index(activity, len(task.phases)), len(problem.row_labels), "cases", **options))
    rng = np.random.default_rng(7)
    n = len(task.phases)
    widths = problem.function.numel_in(4) - 2 * n
    least_violation = 0
    for _ in range(4):
        for _, activity in activities(rng, task, widths):
            args = random_arguments(rng, task, problem, activity) + [0.0]
            x_one, status_one, violation_one = (np.array(v).ravel() for v in one(*args))
            x_cases, status_cases, violation_cases = (np.array(v).ravel() for v in per_phase(*args))
            assert status_cases[0] == status_one[0]
            scale = 1.0 + np.max(np.abs(x_one))
            assert np.max(np.abs(violation_cases - violation_one)) <= SAME * scale
            if int(status_one[0]) & StepStatus.LEAST_VIOLATION:
                least_violation += 1        # the least violation is unique, the motion within it not yet (below)
            else:
                assert np.max(np.abs(x_cases - x_one)) <= SAME * scale, (activity, x_one, x_cases)
    assert least_violation >= 1
