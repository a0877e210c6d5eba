"""How well the ticks reported OPTIMAL hold their rows, and how far the generated and interpreted paths differ.

    python benchmarks/feasibility.py            # paper A (both scenes) and B, every trial of their scenes
    python benchmarks/feasibility.py --quick    # one trial each, B for 9 s (900 ticks)

A scene's simulation (``vfdsl simulate``'s closed loop, ``vfdsl.sim.runner``) runs on the generated controller;
at every tick the same arguments (q, inputs, params, dt) also go, in the same order, to an interpreted controller
of the task (``vfdsl.compile(task, backend="interpreted")``). On each path, at each tick reported OPTIMAL, the
excess of the QP's rows and bounds over their bounds, max(lb - a'x, a'x - ub, 0) with x = [dq; slacks] the
path's answer and (a, lb, ub) the tick's QP (``Controller.problem``), is taken; "hard" is the largest over the
hard constraint rows and the variable bounds, "all" over every row (soft rows with their slacks included).
"dq diff" is max |dq_generated - dq_interpreted| over the ticks both report OPTIMAL, "> 1e-10" the number of those
ticks where it exceeds 1e-10, "cost diff" the largest difference of a priority level's cost 1/2 |R x - r|^2 between
the two answers there. tests/test_feasibility.py
asserts the figures docs/runtime.md states ("Feasibility tolerance, measured") on a short run of each scene.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus
from vfdsl.sim.runner import Job, simulate_with
from vfdsl.sim.scene_file import load_settings

ROOT = Path(__file__).resolve().parent.parent
TASKS = ROOT / "tasks"
SCENES = (("paper_a_follow_curve.vf", "paper_a_follow_curve.sim.yaml"),
          ("paper_a_follow_curve.vf", "paper_a_plate_moves.sim.yaml"),
          ("paper_b_virtual_rcm.vf", "paper_b_virtual_rcm.sim.yaml"))
QUICK_DURATION = {"paper_b_virtual_rcm.sim.yaml": 9.0}      # s; the paper A scenes run whole (160 and 80 ticks)
DIFF_REPORTED = 1e-10   # dq differences above this are counted


@dataclass
class Figures:
    """One scene's measurement (SI: m or rad per tick; a row's own unit for rows)."""

    ticks: int = 0
    optimal: dict = field(default_factory=lambda: {"native": 0, "interpreted": 0})
    hard_excess: dict = field(default_factory=lambda: {"native": 0.0, "interpreted": 0.0})
    all_excess: dict = field(default_factory=lambda: {"native": 0.0, "interpreted": 0.0})
    over_1e9: dict = field(default_factory=lambda: {"native": 0, "interpreted": 0})   # OPTIMAL ticks off by > 1e-9
    dq_diff: float = 0.0
    dq_diff_ticks: int = 0          # ticks (both OPTIMAL) where the paths differ by more than DIFF_REPORTED
    cost_diff: float = 0.0          # largest |cost_generated - cost_interpreted| of a priority level (both OPTIMAL)
    both_optimal: int = 0


class _Twin:
    """The generated controller as the simulator sees it; every step also runs the interpreted one on the same
    arguments and both answers are measured into ``figures``."""

    def __init__(self, native, interpreted, figures: Figures):
        self._native, self._interpreted, self.figures = native, interpreted, figures
        labels = native.assembled.row_labels
        n = native.nq + len(native.assembled.slack_labels)
        self._hard = np.concatenate([np.ones(n, bool), [not label.soft for label in labels]])

    def __getattr__(self, name):
        return getattr(self._native, name)

    def reset(self):
        self._native.reset()
        self._interpreted.reset()

    def step(self, q, inputs=None, params=None, dt=None):
        f = self.figures
        f.ticks += 1
        answers, xs = {}, {}
        qp = self._native.problem(q, inputs, params, dt)
        for kind, ctrl in (("native", self._native), ("interpreted", self._interpreted)):
            dq = np.array(ctrl.step(q, inputs, params, dt))
            if ctrl.status & ~StepStatus.UNCERTIFIED:      # phase 1's answers only
                continue
            x = np.array(ctrl._runner.x).ravel()
            ax = qp.A @ x
            excess = np.maximum(np.maximum(qp.lb - ax, ax - qp.ub), 0.0)
            f.optimal[kind] += 1
            f.hard_excess[kind] = max(f.hard_excess[kind], float(excess[self._hard].max(initial=0.0)))
            f.all_excess[kind] = max(f.all_excess[kind], float(excess.max(initial=0.0)))
            f.over_1e9[kind] += int(excess.max(initial=0.0) > 1e-9)
            answers[kind], xs[kind] = dq, x
        if len(answers) == 2:
            f.both_optimal += 1
            diff = float(np.abs(answers["native"] - answers["interpreted"]).max())
            f.dq_diff = max(f.dq_diff, diff)
            f.dq_diff_ticks += int(diff > DIFF_REPORTED)
            for level in qp.levels:
                cost_n, cost_i = (0.5 * float(np.sum((level.R @ x - level.r) ** 2)) for x in xs.values())
                f.cost_diff = max(f.cost_diff, abs(cost_n - cost_i))
        return self._native.step(q, inputs, params, dt)     # the loop follows the generated path (its last answer)


def measure(task_file: str | Path, scene: str | Path, trials: int | None = None,
            duration: float | None = None) -> Figures:
    """The figures of one scene's simulation (its own trials and duration unless given)."""
    task = vfdsl.load(task_file)
    settings = load_settings(task, scene)
    changes = {k: v for k, v in (("trials", trials), ("duration", duration)) if v is not None}
    settings = settings.replace(**changes)
    native = vfdsl.compile(task)
    interpreted = vfdsl.compile(task, backend="interpreted")
    robot = Robot.load(task.robots[0].urdf, Path(task.file).parent)
    figures = Figures()
    twin = _Twin(native, interpreted, figures)
    for trial in range(settings.trials):
        simulate_with(Job(str(task_file), settings, trial), task, twin, robot, None)
    return figures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one trial per scene, B for 9 s")
    args = parser.parse_args(argv)
    print(f"{'scene':<32}{'ticks':>7}{'optimal g/i':>13}{'hard excess g / i':>22}{'all rows g / i':>20}"
          f"{'> 1e-9 g/i':>12}{'dq diff':>10}{'> 1e-10':>9}{'cost diff':>11}")
    for task_file, scene in SCENES:
        f = measure(TASKS / task_file, TASKS / scene, 1 if args.quick else None,
                    QUICK_DURATION.get(scene) if args.quick else None)
        print(f"{scene:<32}{f.ticks:>7}{f.optimal['native']:>7}/{f.optimal['interpreted']:<5}"
              f"{f.hard_excess['native']:>11.2g} / {f.hard_excess['interpreted']:<8.2g}"
              f"{f.all_excess['native']:>9.2g} / {f.all_excess['interpreted']:<8.2g}"
              f"{f.over_1e9['native']:>6}/{f.over_1e9['interpreted']:<5}{f.dq_diff:>10.2g}{f.dq_diff_ticks:>9}"
              f"{f.cost_diff:>11.2g}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
