"""``vfdsl check``: prove a fixture is sound before it touches a robot.

    report = vfdsl.check(vfdsl.load("tasks/paper_b_virtual_rcm.vf"))
    print(report.render_text()); report.exit_status()      # 0 sound, 1 an error

Analyses, one module each: the polytopes behind the rows (:mod:`.polytope`), the tolerances
(:mod:`.tolerance`), feasibility at the start with an irreducible infeasible subset (:mod:`.feasibility`),
each constraint's error at the start (:mod:`.residuals`), the frames' kinematics (:mod:`.kinematics`),
how fast a port close to the tracked point lets the tool move it sideways (:mod:`.lever`),
the closed loop with the hands off (:mod:`.handsoff`), mesh fixtures (:mod:`.meshes`), configurations the fixture reaches under random
input (:mod:`.sampling`), declarations or constraints that do nothing or contradict (:mod:`.hygiene`), a
procedure's phase machine, monitors and transitions (:mod:`.procedure`), and teleoperation's haptic passivity and
workspace (:mod:`.teleop`).
Findings and their rendering: :mod:`.report`; docs/check.md explains every code.
"""

from __future__ import annotations

import time

from vfdsl.check import (feasibility, handsoff, hygiene, kinematics, lever, meshes, polytope, procedure, residuals,
                         sampling, teleop, tolerance)
from vfdsl.check.linearized import Linearization
from vfdsl.check.report import Finding, Report, Severity
from vfdsl.ir import model as ir

DEFAULT_OVERSHOOT = 0.10
MAX_OVERSHOOT = 10.0           # 1000%: a polytope's worst error may not be accepted at more than 11 x its tolerance

__all__ = ["DEFAULT_OVERSHOOT", "MAX_OVERSHOOT", "checked_overshoot", "Finding", "Report", "Severity", "check"]


def check(task: ir.Task, *, overshoot: float = DEFAULT_OVERSHOOT, samples: int = sampling.DEFAULT_SAMPLES,
          seed: int = 0, backend: str = "auto") -> Report:
    """Every analysis of ``task``. ``overshoot``: the largest accepted excess of a polytope's worst error
    over its tolerance (0.10 = 10%); ``samples``, ``seed``: the random walk of the sampled analysis (0
    samples skips it); ``backend``: how the closed-loop analyses run the controller (see
    :func:`vfdsl.compile`)."""
    from vfdsl.errors import VfError
    from vfdsl import limits

    task = ir.checked_task(task, "check")
    overshoot = checked_overshoot(overshoot)
    if not (isinstance(samples, int) and not isinstance(samples, bool) and 0 <= samples <= limits.CHECK_SAMPLES):
        raise VfError(f"samples must be a whole number from 0 to {limits.CHECK_SAMPLES:,}, got {samples!r}")
    if not (isinstance(seed, int) and not isinstance(seed, bool) and 0 <= seed <= limits.SEED):
        raise VfError(f"seed must be a whole number from 0 to {limits.SEED:,}, got {seed!r}")
    started = time.perf_counter()
    report = Report(task.name, task.file)
    timings = report.figures.setdefault("timings", {})
    run = _runner(report.findings, timings)

    statements = procedure.every_statement(task)
    report.bounds = polytope.bounds_table(statements)
    run("polytope", polytope.analyse, statements, overshoot)
    run("tolerance", tolerance.analyse_values, statements)
    run("tolerance", tolerance.analyse_speeds, statements)
    run("hygiene", hygiene.weight_span, task)
    if procedure.is_procedure(task):
        run("hygiene", procedure.unused, task)
        run("procedure", procedure.analyse, task)
        run("teleop", teleop.anchors, task)
    else:
        run("hygiene", hygiene.unused, task)
    if task.start is None:
        report.add([Finding("no-start", Severity.WARNING,
                            "the scene gives no start configuration: feasibility, residuals, kinematics, "
                            "hands-off and sampled checks are skipped", task.span,
                            "add `start:` to the task's scene file", "task")])
    else:
        if task.scene.period is None:
            report.add([Finding("no-period", Severity.WARNING,
                                "the scene gives no control period: the checks assume 10 ms", task.span,
                                "add `period:` to the task's scene file", "task")])
        analysed = {"": task} if not task.phases else procedure.phase_tasks(task, backend)
        found: dict[str, list[Finding]] = {}
        for phase, one in analysed.items():
            figures = report.figures if not phase else report.figures.setdefault("phases", {}).setdefault(phase, {})
            found[phase] = ([procedure.not_compiled(task, phase)] if one is None
                            else _compiled(one, samples, seed, backend, figures, timings))
        report.add(found[""] if not task.phases else procedure.per_phase(found, report.findings))
    if procedure.is_procedure(task):          # after the phases' analyses: their reach per tick bounds the funnels
        run("procedure", procedure.entries, task, report.figures.get("phases", {}))
    report.figures["seconds"] = time.perf_counter() - started
    report.findings = [_with_param_sources(finding, statements) for finding in report.findings]
    return report


def _runner(findings: list[Finding], timings: dict):
    """run(stage, analysis, *args): one analysis, its findings appended to ``findings`` and its time added to
    ``timings[stage]``."""
    def run(stage: str, analysis, *args) -> None:
        begin = time.perf_counter()
        findings.extend(analysis(*args))
        timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - begin
    return run


def _compiled(task: ir.Task, samples: int, seed: int, backend: str, figures: dict, timings: dict) -> list[Finding]:
    """The analyses of a task's compiled controller (of one moment: a procedure's are run per phase), at its start;
    ``figures`` and ``timings`` get their numbers."""
    from vfdsl.pipeline import compile as compile_task

    findings: list[Finding] = []
    run = _runner(findings, timings)
    begin = time.perf_counter()
    controller = compile_task(task, backend=backend)
    linear = Linearization(task, controller.assembled.context)
    robot = linear.robot
    rows = linear.rows(task.start)
    _check_magnitudes(rows)
    timings["compile"] = timings.get("compile", 0.0) + time.perf_counter() - begin
    run("tolerance", tolerance.analyse_at_start, rows, robot.resolution, robot.nq, linear.period, figures)
    run("feasibility", feasibility.analyse, rows, robot.nq, figures, linear.speed_bound())
    run("residuals", residuals.analyse, task, linear, rows, task.start)
    run("residuals", residuals.soft_at_start, task, linear, rows, task.start, robot.nq, figures)
    walked = None
    if samples > 0:                            # the states the fixture reaches: for sampling and redundancy
        begin = time.perf_counter()
        walked = sampling.walk(controller, task, linear, samples, seed)
        timings["sampling"] = timings.get("sampling", 0.0) + time.perf_counter() - begin
    reached = list(walked[0][sampling.HOLD::sampling.HOLD]) if walked else []
    run("hygiene", hygiene.redundant, rows, robot.nq, reached, linear.rows)
    run("hygiene", hygiene.contradictory, rows, robot.nq)
    run("kinematics", kinematics.analyse, robot, task, task.start, figures)
    run("lever", lever.analyse, task, linear, rows, task.start, figures)
    run("meshes", meshes.analyse, task, robot, task.start, linear.period, figures)
    run("handsoff", handsoff.analyse, controller, task, linear, figures)
    run("teleop", teleop.passivity, task, linear.period)
    run("teleop", teleop.workspace, controller, task, linear.period, figures)
    if walked is not None:
        run("sampling", sampling.analyse, controller, task, linear, samples, seed, figures, walked)
    return findings


def _with_param_sources(finding: Finding, task: ir.Task) -> Finding:
    """An error or warning about a constraint, with a note per param the constraint reads: where it is declared
    and where its value is set (the task's default, or the scene file), since that is where a mistaken value
    (a flipped normal, a pivot out of reach) is mended."""
    from dataclasses import replace

    from vfdsl.compiler.derived import leaves

    if finding.severity == Severity.NOTE or finding.span is None:
        return finding
    notes = []
    for c in task.constraints:
        if c.span != finding.span:
            continue
        for name in dict.fromkeys(leaf.name for arg in c.args.values() for leaf in leaves(arg)
                                  if isinstance(leaf, ir.ParamRef)):
            decl = task.param(name)
            for d in ([decl] + ([task.param(decl.frame)] if decl.frame else [])):
                elsewhere = d.value_span and (d.value_span.file, d.value_span.line) != (d.span.file, d.span.line)
                set_at = f", its value set at {d.value_span}" if elsewhere else ""
                note = f"reads param '{d.name}', declared at {d.span}{set_at}"
                if note not in notes:
                    notes.append(note)
    return replace(finding, notes=finding.notes + tuple(notes)) if notes else finding


def _check_magnitudes(rows) -> None:
    """Refuse rows the linear programs cannot hold (a number beyond ``limits.ROW_VALUE`` m or rad, or not
    finite where it must be): geometry kilometres from the robot, most likely a unit slip, at the
    constraint's line."""
    import numpy as np

    from vfdsl.ir.constraints import describe
    from vfdsl.errors import VfError
    from vfdsl import limits

    for r in rows:
        values = np.concatenate([r.A.ravel(), r.lb[np.isfinite(r.lb) | np.isnan(r.lb)],
                                 r.ub[np.isfinite(r.ub) | np.isnan(r.ub)]])
        if not values.size:
            continue
        worst = float(np.max(np.abs(values))) if not np.isnan(values).any() else float("nan")
        if not worst <= limits.ROW_VALUE:
            raise VfError(f"at the start, the rows of {describe(r.constraint)} hold {worst:g} (m or rad): the limit "
                          f"is {limits.ROW_VALUE:g}; its geometry lies far beyond any robot's reach",
                          r.constraint.span, hint="is a point, a distance or a frame offset in the wrong unit?")


def checked_overshoot(value) -> float:
    """``value`` as a float when it is a real number in (0, MAX_OVERSHOOT); else VfError (NaN would pass
    every polytope silently, a negative one fail every polytope)."""
    from vfdsl.errors import VfError
    from vfdsl.runtime.values import real_scalar
    fraction = real_scalar(value, "the overshoot")
    if not 0 < fraction < MAX_OVERSHOOT:
        raise VfError(f"the overshoot must be between 0 and {MAX_OVERSHOOT:g} ({MAX_OVERSHOOT:.0%}), got {fraction:g}",
                      hint="a fraction: 0.10 accepts a polytope whose worst error is 10% over its tolerance")
    return fraction
