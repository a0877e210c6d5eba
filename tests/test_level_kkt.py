"""Every level exact at cold states (issue 35, item 2): at random states of every example task, with random pushes,
each tick reported OPTIMAL is checked, level by level, by that level's own KKT conditions over the hard rows and
the optimal sets of the levels above, computed here with scipy's bounded least squares (tests/levels_reference.py,
kkt_excess): independent of the controller's solvers and certificate. The hard rows hold within 1e-9 and every
level's residual is within 1e-9 of its gradient's scale, on both paths; the two paths give the same dq.

The states are cold (a fresh controller for each, no previous tick), 1e-5 rad from the start (inside the fixtures) and
1e-3 rad (mostly outside them), every run-time param moved as far (m, rad) from its default. A least-violation tick is
checked the same way over the least-violation set S, which the reference computes itself
(levels_reference.least_violation_set: its own phase 2 (A), its own S); where the controller found no certificate its
answer is (A)'s, x_A, the reference's within 1e-9 (at most half of a task's least-violation ticks: 3 of polyline_guide's
8 here, none on most tasks; benchmarks/least_violation.py counts them on more states), and its status has the bit
UNCERTIFIED: a tick without it is exact, on both paths. A least-violation tick goes a of phase 2's step
(docs/runtime.md, Phase 2 (C)): both paths' answers are a times the whole step (the task's step built with
backtrack=False) within 1e-10, a restated from its definition (levels_reference.step_length), and the levels are
judged on the whole step."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TASKS_DIR
from levels_reference import kkt_excess, least_violation_set, step_length, whole_step

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime import lexls
from vfdsl.runtime.qp import StepStatus

STATES = 16
TASKS = sorted(p.stem for p in TASKS_DIR.glob("*.vf"))


def random_params(ctrl, rng, scale):
    """Every run-time param moved from its default by a normal of ``scale`` per entry (m, rad; a curve's points
    each), or None for a task without params."""
    layout = ctrl._values.layout
    params = {}
    for name, slot in layout.slots.items():
        if slot.size and slot.type != "mesh":
            value = layout.defaults[slot.offset:slot.offset + slot.size] + rng.normal(scale=scale, size=slot.size)
            params[name] = value.reshape(-1, 3) if slot.type == "curve" else value
    return params or None


@pytest.mark.parametrize("name", TASKS)
def test_every_level_is_exact_at_cold_states_on_both_paths(name):
    task = vfdsl.load(TASKS_DIR / f"{name}.vf")
    interpreted = vfdsl.compile(task, backend="interpreted")       # (its solves hold no state between ticks)
    robot = Robot.load(task.robots[0].urdf)
    rng = np.random.default_rng(21)
    damping_last = interpreted.assembled.last_level_is_damping
    whole = whole_step(interpreted)
    checked = least = uncertified = 0
    for k in range(STATES):
        scale = 1e-5 if k % 2 == 0 else 1e-3
        q = np.clip(np.array(task.start) + rng.normal(scale=scale, size=robot.nq), robot.lower, robot.upper)
        inputs = {name: rng.normal(scale=2.0, size=size) for name, size in interpreted.input_sizes.items()}
        params = random_params(interpreted, rng, scale)
        answers = {}
        # a fresh generated controller: cold, no previous tick's working set to start from
        for backend, ctrl in (("native", vfdsl.compile(task, backend="native")), ("interpreted", interpreted)):
            answers[backend] = (ctrl.step(q, inputs, params), ctrl.status, np.array(ctrl._runner.x))
        (dq_n, status_n, x_n), (dq_i, status_i, x_i) = answers["native"], answers["interpreted"]
        assert status_n == status_i
        assert np.max(np.abs(dq_n - dq_i)) <= 1e-10, (k, status_n, np.max(np.abs(dq_n - dq_i)))
        qp = interpreted.problem(q, inputs, params)
        violated, certified = status_n & StepStatus.LEAST_VIOLATION, not status_n & StepStatus.UNCERTIFIED
        answers = (x_n, x_i)
        if violated:
            x_a, qp = least_violation_set(qp, interpreted.assembled.row_groups)
            least += 1
            # the levels are judged on phase 2's whole step, which the tick takes a of (Phase 2 (C), restated)
            x_whole = np.array(whole(*interpreted._data(q, inputs, params, None), 0.0)[0]).ravel()
            a = step_length(interpreted, q, inputs, params, x_whole)
            assert max(np.max(np.abs(x.ravel() - a * x_whole)) for x in answers) <= 1e-10, (k, a)
            answers = (x_whole,) if a < 1 else answers
        if status_n & ~(StepStatus.LEAST_VIOLATION | StepStatus.UNCERTIFIED):
            continue
        checked += 1
        for x in answers:
            residuals, excess = kkt_excess(qp, x, damping_last)
            assert excess <= 1e-9, (k, excess)
            if violated and not certified:          # the status says no certificate: x_A
                assert np.max(np.abs(x - x_a)) <= 1e-9, (k, residuals)
                uncertified += x is answers[0]
                continue
            assert max(residuals, default=0.0) <= 1e-9, (k, status_n, residuals)
    assert checked >= STATES // 2
    assert uncertified <= max(1, least // 2), (uncertified, least)     # (measured: polyline_guide 3 of 8)


def test_the_status_says_where_no_certificate_was_found(monkeypatch):
    """Paper A (two levels), the interpreted path, its certificates refused (lexls.polish, lexls.from_feasible): phase
    1's answer is then DAQP's, within its tolerance of the certified one, with the status bit UNCERTIFIED; a
    least-violation tick's is (A)'s x_A, with LEAST_VIOLATION and UNCERTIFIED. Certified, neither tick has the bit."""
    task = vfdsl.load(TASKS_DIR / "paper_a_follow_curve.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")
    push = {"f": np.array([2.0, -1.0, 0.5])}
    outside = np.array(task.start) + 1e-3
    certified = ctrl.step(task.start, push), ctrl.status
    least = ctrl.step(outside, push), ctrl.status
    assert certified[1] == StepStatus.OPTIMAL
    assert least[1] == StepStatus.LEAST_VIOLATION
    x_a, _ = least_violation_set(ctrl.problem(outside, push), ctrl.assembled.row_groups)
    monkeypatch.setattr(lexls, "polish", lambda H, g, A, lower, upper, breaks, x: (x, False))
    monkeypatch.setattr(lexls, "from_feasible", lambda H, f, A, lo, up, levels, x0: (x0, False))
    dq = ctrl.step(task.start, push)
    assert ctrl.status == StepStatus.UNCERTIFIED
    assert 0 < np.max(np.abs(dq - certified[0])) <= 1e-6
    dq = ctrl.step(outside, push)
    assert ctrl.status == StepStatus.LEAST_VIOLATION | StepStatus.UNCERTIFIED
    assert np.max(np.abs(np.array(ctrl._runner.x).ravel() - x_a)) <= 1e-9
    assert np.max(np.abs(dq - least[0])) > 1e-9           # the levels moved the certified answer within S
