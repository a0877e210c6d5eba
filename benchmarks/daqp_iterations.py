"""How many DAQP iterations one solve takes, on every example task: the measure behind the iteration limit of each
solve (vfdsl.codegen.solve_plan.ITER_LIMIT, docs/runtime.md "A bounded tick").

    python benchmarks/daqp_iterations.py                # every example, 2,000 closed-loop ticks and 300 cold states
    python benchmarks/daqp_iterations.py --ticks 500 --cold 50 --only paper_a_follow_curve

Every solve of the interpreted controller goes through the daqp package cold (vfdsl.runtime.daqp_solve.solve_daqp),
the same problem, settings and rows the generated C solves (which starts from the previous tick's working set, so
that its steady ticks take fewer). The states: a closed loop from the task's start under the generic hand of
export_tail.py, then cold states, each joint uniform in its limits (most outside the task's fixtures: their
least-violation ticks), with the same inputs. Printed per task: solves, iterations mean, p99.9 and max, and the
solve that took the most (its rows).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import vfdsl
from vfdsl.kinematics.robot import Robot
from vfdsl.codegen import solve_plan
from vfdsl.runtime import daqp_solve

import export_tail

SOLVES_PER_TICK = 6
"""DAQP solves a tick makes at most: phase 1 (one, or LEVEL_ATTEMPTS = 3 with priority levels) and phase 2's (A), its
retry where DAQP fails it, and (B)."""
MANY = 50
"""Solves of at least this many iterations give the time per iteration (DAQP's own solve time over its iterations:
the setup and the first factorization spread over many; below, a solve's fixed cost dominates)."""


def measure(path, ticks: int, cold: int, seed: int) -> dict:
    task = vfdsl.load(path)
    ctrl = vfdsl.compile(task, backend="interpreted")
    robot = Robot.load(task.robots[0].urdf)
    counts: list[tuple[int, int, float]] = []
    solve = daqp_solve.solve_daqp

    def counted(H, g, A, lower, upper, *args):
        x, flag, iterations, seconds = solve(H, g, A, lower, upper, *args)
        counts.append((iterations, len(lower), seconds))
        return x, flag, iterations, seconds

    daqp_solve.solve_daqp = counted
    try:
        inputs = export_tail.hand(task)
        q = np.array(task.start, dtype=float)
        for k in range(ticks):
            q = q + ctrl.step(q, inputs(k, q))
        rng = np.random.default_rng(seed)
        lower, upper = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
        for k in range(cold):
            ctrl.reset()
            ctrl.step(rng.uniform(lower, upper), inputs(k, q))
    finally:
        daqp_solve.solve_daqp = solve
    iterations = np.array([c for c, _, _ in counts])
    worst = int(np.argmax(iterations))
    per_iteration = max((s / c for c, _, s in counts if c >= MANY), default=float("nan"))
    return {"task": path.stem, "solves": len(counts), "mean": float(iterations.mean()),
            "p999": float(np.percentile(iterations, 99.9)), "max": int(iterations[worst]), "rows": counts[worst][1],
            "per_iteration": per_iteration, "longest": max(s for _, _, s in counts)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2000, help="closed-loop ticks per task (default 2,000)")
    parser.add_argument("--cold", type=int, default=300, help="cold random states per task (default 300)")
    parser.add_argument("--only", nargs="*", help="task names (file stems); default every example")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    paths = [p for p in export_tail.example_tasks() if not args.only or p.stem in args.only]
    print(f"DAQP iterations per solve, {args.ticks} closed-loop ticks and {args.cold} cold states per task "
          f"(limit {solve_plan.ITER_LIMIT})")
    print(f"{'task':<30} {'solves':>8} {'mean':>7} {'p99.9':>7} {'max':>5} {'rows of the max':>16} "
          f"{'us/iteration':>13} {'longest solve us':>17}")
    worst, slowest, longest = 0, 0.0, 0.0
    for path in paths:
        print(f"[{path.stem}]", file=sys.stderr, flush=True)
        r = measure(path, args.ticks, args.cold, args.seed)
        worst = max(worst, r["max"])
        slowest, longest = np.nanmax([slowest, r["per_iteration"]]), max(longest, r["longest"])
        print(f"{r['task']:<30} {r['solves']:>8} {r['mean']:>7.2f} {r['p999']:>7.1f} {r['max']:>5} {r['rows']:>16} "
              f"{r['per_iteration'] * 1e6:>13.3f} {r['longest'] * 1e6:>17.1f}", flush=True)
    limit = solve_plan.ITER_LIMIT
    bound = longest + limit * slowest
    print(f"largest: {worst} iterations, the limit {limit} ({limit / max(worst, 1):.1f}x); slowest iteration "
          f"{slowest * 1e6:.3f} us (solves of {MANY}+ iterations), longest solve {longest * 1e6:.0f} us: a solve that "
          f"reaches the limit takes about {bound * 1e3:.2f} ms (the longest solve plus {limit} iterations), a tick at "
          f"most {SOLVES_PER_TICK} solves, {SOLVES_PER_TICK * bound * 1e3:.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
