"""Least-violation ticks: are the priority levels exact over the least-violation set, and do the two paths agree?

    python benchmarks/least_violation.py                 # every example task, 16 states at 1e-3 and at 1e-2 rad
    python benchmarks/least_violation.py --states 4      # fewer states (a quick look)

At random cold states near each task's start (the joints moved by a normal of the given scale, random pushes of
scale 2, a fresh generated controller for each state), every tick both paths report LEAST_VIOLATION is checked
against an independent reference (tests/levels_reference.py): its own phase-2 (A), solved by DAQP's Python package,
gives its own least-violation set S; each level of the answer is judged by its KKT conditions over S and the optimal
sets of the levels above (scipy's bounded least squares). "not exact": ticks where some level's residual exceeds
1e-9 of its gradient's scale (the controller then found no certificate, and its answer is (A)'s x_A); "flagged":
ticks whose status has the bit UNCERTIFIED (the controller saying it found no certificate); "level": the
largest residual; "S": the answer's largest excess over S; "paths": max |dq_generated - dq_interpreted|. The
levels are judged on phase 2's whole step (the task's step built with ``backtrack=False``); the tick then goes a of
the way (docs/runtime.md, Phase 2 (C)), a restated here from its definition (levels_reference.step_length):
"shortened": ticks with a < 1; "a x": max |x - a x_whole| over both paths.
docs/runtime.md (Phase 2) quotes this table; tests/test_level_kkt.py checks the same on fewer states.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from levels_reference import kkt_excess, least_violation_set, step_length, whole_step  # noqa: E402

import vfdsl  # noqa: E402
from vfdsl.kinematics.robot import Robot  # noqa: E402
from vfdsl.runtime.qp import StepStatus  # noqa: E402

SCALES = ((1e-3, 5), (1e-2, 7))      # (rad, seed)


def measure(name: str, states: int, scale: float, seed: int) -> list[tuple]:
    """(largest level residual, excess over S, path difference, flagged, step length, |x - a x_whole|) per
    least-violation tick: the levels judged on phase 2's whole step, the answers against its length restated."""
    task = vfdsl.load(ROOT / "tasks" / f"{name}.vf")
    interpreted = vfdsl.compile(task, backend="interpreted")
    whole = whole_step(interpreted)
    robot = Robot.load(task.robots[0].urdf)
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(states):
        q = np.clip(np.array(task.start) + rng.normal(scale=scale, size=robot.nq), robot.lower, robot.upper)
        inputs = {input_name: rng.normal(scale=2.0, size=size) for input_name, size in interpreted.input_sizes.items()}
        answers = []
        for ctrl in (vfdsl.compile(task, backend="native"), interpreted):
            dq = ctrl.step(q, inputs)
            answers.append((dq, ctrl.status, np.array(ctrl._runner.x)))
        status = answers[0][1]
        if status != answers[1][1] or not status & StepStatus.LEAST_VIOLATION:
            continue
        qp = interpreted.problem(q, inputs)
        _, over_s = least_violation_set(qp, interpreted.assembled.row_groups)
        x_whole = np.array(whole(*interpreted._data(q, inputs, None, None), 0.0)[0]).ravel()
        residuals, excess = kkt_excess(over_s, x_whole, interpreted.assembled.last_level_is_damping)
        a = step_length(interpreted, q, inputs, None, x_whole)
        rows.append((max(residuals), excess, float(np.max(np.abs(answers[0][0] - answers[1][0]))),
                     bool(status & StepStatus.UNCERTIFIED), a,
                     max(float(np.max(np.abs(x.ravel() - a * x_whole))) for _, _, x in answers)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=16, help="random states per task and scale (default 16)")
    states = parser.parse_args().states
    names = sorted(p.stem for p in (ROOT / "tasks").glob("*.vf"))
    print(f"{'task':30s} {'scale':>6s} {'LV ticks':>8s} {'not exact':>9s} {'flagged':>7s} {'level':>8s} {'S':>8s} "
          f"{'paths':>8s} {'shortened':>9s} {'a x':>8s}")
    total = bad = flagged = shortened = 0
    worst_paths = worst_length = 0.0
    for scale, seed in SCALES:
        for name in names:
            rows = measure(name, states, scale, seed)
            if not rows:
                continue
            level, excess, paths, _, _, length = (max(column) for column in zip(*rows))
            not_exact, said = sum(r[0] > 1e-9 for r in rows), sum(r[3] for r in rows)
            short = sum(r[4] < 1 for r in rows)
            total, bad, flagged, shortened = total + len(rows), bad + not_exact, flagged + said, shortened + short
            worst_paths, worst_length = max(worst_paths, paths), max(worst_length, length)
            print(f"{name:30s} {scale:6.0e} {len(rows):8d} {not_exact:9d} {said:7d} {level:8.1e} {excess:8.1e} "
                  f"{paths:8.1e} {short:9d} {length:8.1e}", flush=True)
    print(f"least-violation ticks: {total}, not exact: {bad}, status UNCERTIFIED: {flagged}, "
          f"paths within {worst_paths:.1e}; steps shortened: {shortened}, answers within {worst_length:.1e} of the "
          "restated length times the whole step")


if __name__ == "__main__":
    main()
