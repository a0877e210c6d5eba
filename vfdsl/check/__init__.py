"""``vfdsl check``: prove a fixture is sound before it touches a robot.

    report = vfdsl.check(vfdsl.load("tasks/paper_b_virtual_rcm.vf"))
    print(report.render_text()); report.exit_status()      # 0 sound, 1 an error

Analyses, one module each: the polytopes behind the rows (:mod:`.polytope`), the tolerances
(:mod:`.tolerance`), feasibility at the start with an irreducible infeasible subset (:mod:`.feasibility`),
each constraint's error at the start (:mod:`.residuals`), the frames' kinematics (:mod:`.kinematics`),
the closed loop with the hands off (:mod:`.handsoff`), configurations the fixture reaches under random
input (:mod:`.sampling`), and declarations or constraints that do nothing or contradict (:mod:`.hygiene`).
Findings and their rendering: :mod:`.report`; docs/check.md explains every code.
"""

from __future__ import annotations

import time

from vfdsl.check import feasibility, handsoff, hygiene, kinematics, polytope, residuals, sampling, tolerance
from vfdsl.check.linearized import Linearization
from vfdsl.check.report import Finding, Report, Severity
from vfdsl.ir import model as ir

DEFAULT_OVERSHOOT = 0.10

__all__ = ["DEFAULT_OVERSHOOT", "Finding", "Report", "Severity", "check"]


def check(task: ir.Task, *, overshoot: float = DEFAULT_OVERSHOOT, samples: int = sampling.DEFAULT_SAMPLES,
          seed: int = 0, backend: str = "auto") -> Report:
    """Every analysis of ``task``. ``overshoot``: the largest accepted excess of a polytope's worst error
    over its tolerance (0.10 = 10%); ``samples``, ``seed``: the random walk of the sampled analysis (0
    samples skips it); ``backend``: how the closed-loop analyses run the controller (see
    :func:`vfdsl.compile`)."""
    from vfdsl.pipeline import compile as compile_task

    started = time.perf_counter()
    report = Report(task.name, task.file)
    report.bounds = polytope.bounds_table(task)
    report.add(polytope.analyse(task, overshoot))
    report.add(tolerance.analyse_values(task))
    report.add(hygiene.unused(task))
    if task.start is None:
        report.add([Finding("no-start", Severity.WARNING,
                            "the scene gives no start configuration: feasibility, residuals, kinematics, "
                            "hands-off and sampled checks are skipped", task.span,
                            "add `start:` to the task's scene file", "task")])
        report.figures["seconds"] = time.perf_counter() - started
        return report
    if task.scene.period is None:
        report.add([Finding("no-period", Severity.WARNING,
                            "the scene gives no control period: the checks assume 10 ms", task.span,
                            "add `period:` to the task's scene file", "task")])
    controller = compile_task(task, backend=backend)
    linear = Linearization(task, controller.assembled.context)
    robot = linear.robot
    rows = linear.rows(task.start)
    report.add(tolerance.analyse_at_start(rows, robot.resolution, robot.nq, linear.period))
    report.add(feasibility.analyse(rows, robot.nq, report.figures))
    report.add(residuals.analyse(task, linear, rows, task.start))
    report.add(hygiene.redundant(rows, robot.nq))
    report.add(hygiene.contradictory(rows, robot.nq))
    report.add(kinematics.analyse(robot, task, task.start, report.figures))
    report.add(handsoff.analyse(controller, task, linear, report.figures))
    if samples > 0:
        report.add(sampling.analyse(controller, task, linear, samples, seed, report.figures))
    report.figures["seconds"] = time.perf_counter() - started
    return report
