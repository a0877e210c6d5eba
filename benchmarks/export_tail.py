"""Every example task's exported C tick, its tail included: median, p99, p99.9 and max, in wall time and in the
thread's CPU time (issue 35: "each task's p99.9 in C").

    python benchmarks/export_tail.py                  # 50,000 timed ticks per task
    python benchmarks/export_tail.py --ticks 10000 --only paper_b_virtual_rcm keep_out

Each task under tasks/ (and tasks/procedures/, tasks/teleop/) is exported (`vfdsl export`) and built with make and
CFLAGS="-O3 -march=native" (the flags of vfdsl's own build); a closed-loop trajectory of 4,000 ticks is recorded
with Controller.step() from the task's start under a generic hand (hand()): each motion input pushed at its
export self-test size (a firm hand: 3 N, 0.02 N m, 10 mm/s, 0.05 rad/s) in a direction that turns slowly, with a
fast wobble; a button left released; a master (a pose) moved in 30 mm circles that dip 20 mm and turn 0.2 rad
(tasks/teleop/: through contact with the bone, along and off the line). benchmarks/export_tick.c calls <api>_step on
those states in turn (1,000 warm-up ticks, then the timed ticks): the wall time (CLOCK_MONOTONIC) and the thread's
CPU time (CLOCK_THREAD_CPUTIME_ID) around each call, with no Python in that process. The CPU time is what the
tick costs (plus the two wall-clock reads it brackets, ~0.3 us); the wall time adds what the shared machine took
from it (a preempted tick): on this 2-vCPU VM the wall p99.9 and max are mostly the machine's, compare the CPU
columns across tasks and runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl import pipeline
from vfdsl.export import export
from vfdsl.inputs import INPUT_TYPES

import export_tick
import tick_timing as timing

TASKS = Path(__file__).resolve().parent.parent / "tasks"
FLAGS = "-O3 -march=native"
RECORDED = 4_000


def example_tasks() -> list[Path]:
    """The example tasks with a scene that gives their start."""
    return sorted(p for p in [*TASKS.glob("*.vf"), *TASKS.glob("procedures/*.vf"), *TASKS.glob("teleop/*.vf")]
                  if vfdsl.load(p).start is not None)


def hand(task):
    """inputs_of(k, q) for timing.record: every motion part at its self-test size, turning slowly, with a wobble."""
    def inputs(k, q):
        out = {}
        for n, decl in enumerate(task.inputs):
            kind = INPUT_TYPES[decl.type]
            value = np.zeros(kind.size)
            for part in (kind.linear_range, kind.angular_range):
                if part is not None:
                    size = kind.self_test_scale[part.start]
                    phase = 0.7 * n + part.start
                    value[part] = size * np.array([np.sin(0.003 * k + phase), np.cos(0.002 * k + phase),
                                                   0.5 * np.sin(0.7 * k)])
            if decl.type == "pose":             # a master: 30 mm circles, dipping 20 mm, turning 0.2 rad
                value[:] = [0.03 * np.sin(0.003 * k), 0.03 * (np.cos(0.003 * k) - 1), -0.01 * (1 - np.cos(0.002 * k)),
                            0.0, 0.0, 0.2 * np.sin(0.001 * k)]
            out[decl.name] = value
        return out
    return inputs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=50_000, help="timed ticks per task (default 50,000)")
    parser.add_argument("--only", nargs="*", help="task names (file stems) to time; default every example")
    parser.add_argument("--json", help="write the figures to this file")
    args = parser.parse_args(argv)
    paths = [p for p in example_tasks() if not args.only or p.stem in args.only]
    rows = {}
    with tempfile.TemporaryDirectory(prefix="vfdsl-export-tail-") as name:
        tmp = Path(name)
        for path in paths:
            task = vfdsl.load(path)
            timing.log(f"[{path.stem}] exporting, recording {RECORDED} ticks, timing {args.ticks}")
            exported = export(task, tmp / path.stem, cache_dir=tmp / "cache")
            ctrl, _ = pipeline.build(task, backend="native", cache_dir=tmp / "cache")
            dt = task.scene.period
            qs, us, _, _ = timing.record(ctrl, task.start, hand(task), dt, RECORDED)
            states = "\n".join(" ".join(f"{x:.17g}" for x in (*q, *u)) for q, u in zip(qs, us)) + "\n"
            rows[path.stem] = export_tick.c_tick(exported.directory, exported.api, FLAGS, states, dt, args.ticks, tmp)
    machine = timing.machine()
    print(f"vfdsl export: each example's C tick from C, {args.ticks:,} ticks each, CFLAGS={FLAGS}")
    print(f"CPU {machine['cpu']}, {machine['cores_usable']} usable cores, load {machine['loadavg']:.2f}; {machine['cc']}")
    print(f"{'task':<30}{'wall us: median':>16}{'p99':>8}{'p99.9':>8}{'max':>8}   "
          f"{'CPU us: median':>15}{'p99':>8}{'p99.9':>8}{'max':>8}{'optimal':>9}")
    for task_name, s in rows.items():
        c = s["cpu"]
        print(f"{task_name:<30}{s['median_us']:16.2f}{s['p99_us']:8.2f}{s['p999_us']:8.2f}{s['max_us']:8.1f}   "
              f"{c['median_us']:15.2f}{c['p99_us']:8.2f}{c['p999_us']:8.2f}{c['max_us']:8.1f}"
              f"{s['optimal_fraction']:9.1%}")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": machine, "ticks": args.ticks, "flags": FLAGS,
                                               "tasks": rows}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
