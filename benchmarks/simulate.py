"""Speed of `vfdsl simulate`: simulated time against wall time, the cost of a tick against the controller's
step alone (both measured in one run), and a sweep of 1,000 short trials on 1 and 2 local processes and on a
2-worker Dask LocalCluster.

    python benchmarks/simulate.py              # about a minute on 2 cores
    python benchmarks/simulate.py --quick      # 200 trials in the sweep

1. Experiment B, one 60 s trial at 100 Hz (6,000 ticks) with the scene's conditions (resolution, tracker,
   hand with tremor and drift): wall time of the whole trial (closed loop + scoring), best of 5 runs, after
   one warm-up run; the share of it spent inside Controller.step, timed around each call during the same
   run; ticks per second and simulated time / wall time.
2. The sweep: 1,000 trials of experiment B of 0.5 s (50 ticks) each, with different seeds, run in this
   process, in 2 local processes, and on a LocalCluster of 2 worker processes (1 thread each); the
   start-up of pools and clusters is inside the figure (the cluster is timed once more when it is up),
   the compile is not (the controller is in the disk cache). The aggregates are checked to be identical.
Progress goes to stderr; the report to stdout. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TASK = str(ROOT / "tasks" / "paper_b_virtual_rcm.vf")
SCENE = ROOT / "tasks" / "paper_b_virtual_rcm.sim.yaml"


def _timed_trial(settings) -> tuple[float, float, int]:
    """(wall seconds of one trial, seconds inside Controller.step, ticks)."""
    from vfdsl.sim.runner import loaded, make_jobs, run

    ctx = loaded(TASK)
    step = ctx.controller.step
    inside = [0.0]

    def timed_step(*args, **kwargs):
        start = time.perf_counter()
        try:
            return step(*args, **kwargs)
        finally:
            inside[0] += time.perf_counter() - start

    ctx.controller.step = timed_step
    try:
        start = time.perf_counter()
        (result,) = run(make_jobs(TASK, settings))
        wall = time.perf_counter() - start
    finally:
        del ctx.controller.step
    return wall, inside[0], result.ticks


def _sweep(settings, trials: int) -> dict:
    import distributed

    from vfdsl.sim import report
    from vfdsl.sim.runner import make_jobs, run

    jobs = make_jobs(TASK, settings.replace(trials=trials, duration=0.5))
    out, docs = {}, {}
    for label, kwargs in (("1 process", {"workers": 1}), ("2 local processes", {"workers": 2})):
        start = time.perf_counter()
        results = run(jobs, **kwargs)
        out[label] = time.perf_counter() - start
        docs[label] = report.to_json(report.document("b", TASK, settings, results, None))
        print(f"  {label}: {out[label]:.2f} s", file=sys.stderr)
    start = time.perf_counter()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        results = run(jobs, cluster=client)
        label = "Dask LocalCluster, 2 workers"
        out[label] = time.perf_counter() - start
        start = time.perf_counter()
        again = run(jobs, cluster=client)
        out["the same, cluster already up"] = time.perf_counter() - start
    docs[label] = report.to_json(report.document("b", TASK, settings, results, None))
    docs["again"] = report.to_json(report.document("b", TASK, settings, again, None))
    print(f"  {label}: {out[label]:.2f} s", file=sys.stderr)
    same = len(set(docs.values())) == 1
    return {"wall": out, "identical": same, "ticks": sum(r.ticks for r in results)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="200 trials in the sweep instead of 1,000")
    args = parser.parse_args()
    os.environ.setdefault("VFDSL_CACHE", tempfile.mkdtemp(prefix="vfdsl-bench-"))
    import vfdsl
    from vfdsl.sim.scene_file import load_settings

    settings = load_settings(vfdsl.load(TASK), SCENE).replace(trials=1, duration=60.0)
    print("warming up (compile, first trial)", file=sys.stderr)
    _timed_trial(settings)
    runs = [_timed_trial(settings) for _ in range(5)]
    wall, inside, ticks = min(runs)
    print(f"vfdsl simulate benchmark: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f}, Python {platform.python_version()}")
    print()
    print(f"1. experiment B, one trial of {settings.duration:g} s at {settings.period * 1e3:g} ms "
          f"({ticks} ticks), best of {len(runs)}:")
    print(f"   wall {wall:.3f} s = {settings.duration / wall:.0f}x real time, {ticks / wall:,.0f} ticks/s")
    print(f"   per tick: {wall / ticks * 1e6:.1f} us in all, of which Controller.step {inside / ticks * 1e6:.1f} us "
          f"-> {wall / inside:.2f}x the step alone")
    trials = 200 if args.quick else 1000
    print(f"running the sweep of {trials} trials", file=sys.stderr)
    sweep = _sweep(settings, trials)
    print()
    print(f"2. sweep of {trials} trials of 0.5 s ({sweep['ticks']:,} ticks), wall time with start-up:")
    base = sweep["wall"]["1 process"]
    for label, seconds in sweep["wall"].items():
        print(f"   {label:<30} {seconds:7.2f} s   speed-up {base / seconds:.2f}")
    print(f"   identical aggregates: {sweep['identical']}")


if __name__ == "__main__":
    main()
