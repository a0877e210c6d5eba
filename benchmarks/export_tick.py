"""The exported C library's tick, timed from a C program, beside Controller.step() and pink's solve_ik, in one run.

    python benchmarks/export_tick.py                 # 100,000 ticks per figure
    python benchmarks/export_tick.py --ticks 20000   # shorter

For experiments A and B (tasks/paper_a_follow_curve.vf, tasks/paper_b_virtual_rcm.vf): the task is exported
(`vfdsl export`) and built with make, once with the Makefile's default flags (-O3) and once with
CFLAGS="-O3 -march=native" (the flags of vfdsl's own build); a closed-loop trajectory of 4,000 ticks is recorded
with Controller.step() (the inputs of benchmarks/tick.py, from tick_jobs.py); benchmarks/export_tick.c calls
<api>_step on those states in turn (1,000 warm-up ticks, then the timed ticks, clock_gettime around each call: no
Python in that process). Controller.step() is timed on the same states by benchmarks/tick_timing.py's time_step,
and pink's solve_ik (Panda, one FrameTask; benchmarks/tick_jobs.py's pink_baseline) the same number of ticks.
Medians and p99 in us.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import vfdsl
from vfdsl import pipeline
from vfdsl.export import export

import tick_jobs as jobs            # benchmarks/tick.py's drivers and pink baseline, and its timing of step():
import tick_timing as timing        # one method for both reports

BENCH = Path(__file__).resolve().parent
TASKS = BENCH.parent / "tasks"
PROGRAM = BENCH / "export_tick.c"


def c_tick(directory: Path, api: str, flags: str, states: str, dt: float, ticks: int, tmp: Path) -> dict:
    """Build the export in ``directory`` with CFLAGS=``flags`` and time its tick from export_tick.c."""
    subprocess.run(["make", "-s", "clean"], cwd=directory, check=True)
    subprocess.run(["make", "-s", "-j2", f"lib{api}.a", f"CFLAGS={flags}"], cwd=directory, check=True)
    exe = tmp / f"{api}-tick"
    subprocess.run(["cc", "-O2", "-include", str(directory / f"{api}.h"), f"-DAPI={api}", str(PROGRAM),
                    str(directory / f"lib{api}.a"), "-lm", "-pthread", "-o", str(exe)], check=True)
    out = subprocess.run([str(exe), str(ticks), repr(dt)], input=states, capture_output=True, text=True, check=True)
    fields = out.stdout.split()
    wall, cpu = ([float(x) for x in fields[k:k + 4]] for k in (0, 4))
    names = ("median_us", "p99_us", "p999_us", "max_us")
    return {**dict(zip(names, wall)), "cpu": dict(zip(names, cpu)), "ticks": int(fields[8]),
            "optimal_fraction": int(fields[9]) / int(fields[8])}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=100_000, help="timed ticks per figure (default 100,000)")
    args = parser.parse_args(argv)
    machine = timing.machine()
    rows = {}
    with tempfile.TemporaryDirectory(prefix="vfdsl-export-bench-") as name:
        tmp = Path(name)
        for task_name, driver in (("paper_a_follow_curve", jobs.push_along_curve),
                                  ("paper_b_virtual_rcm", jobs.twist_about_cone)):
            task = vfdsl.load(TASKS / f"{task_name}.vf")
            timing.log(f"[{task_name}] exporting and recording")
            exported = export(task, tmp / task_name, cache_dir=tmp / "cache")
            ctrl, _ = pipeline.build(task, backend="native", cache_dir=tmp / "cache")
            dt = task.scene.period
            qs, us, dicts, _ = timing.record(ctrl, task.start, driver(task), dt, 4_000)
            states = "\n".join(" ".join(f"{x:.17g}" for x in (*q, *u)) for q, u in zip(qs, us)) + "\n"
            row = {}
            for label, flags in (("C library, -O3", "-O3"), ("C library, -O3 -march=native", "-O3 -march=native")):
                timing.log(f"[{task_name}] timing the C tick ({label})")
                row[label] = c_tick(exported.directory, exported.api, flags, states, dt, args.ticks, tmp)
            timing.log(f"[{task_name}] timing Controller.step()")
            fresh, _ = pipeline.build(task, backend="native", cache_dir=tmp / "cache")
            row["Controller.step()"] = timing.time_step(fresh, qs, dicts, dt, args.ticks)
            rows[task_name] = row
        timing.log(f"[pink] timing solve_ik ({args.ticks} ticks)")
        pink = jobs.pink_baseline(args.ticks, 0.01)["solve_ik"]
    print(f"vfdsl export: the C tick from C, beside Controller.step() and pink ({args.ticks:,} ticks per figure)")
    print(f"CPU {machine['cpu']}, {machine['cores_usable']} usable cores, load {machine['loadavg']:.2f}; {machine['cc']}")
    print(f"{'task':<24}{'path':<34}{'median us':>10}{'p99 us':>9}{'max us':>9}")
    for task_name, row in rows.items():
        for i, (label, s) in enumerate(row.items()):
            print(f"{task_name if i == 0 else '':<24}{label:<34}{s['median_us']:10.2f}{s['p99_us']:9.2f}{s['max_us']:9.1f}")
    print(f"{'pink solve_ik (Panda)':<24}{'Python, qpsolvers daqp':<34}{pink['median_us']:10.2f}{pink['p99_us']:9.2f}"
          f"{pink['max_us']:9.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
