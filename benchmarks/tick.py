"""Tick-time benchmark of vfdsl's controllers, with pink as the baseline, in one run.

    python benchmarks/tick.py              # full run (a few minutes)
    python benchmarks/tick.py --quick      # short run (~1.5 min): fewer ticks, smaller row sweep
    python benchmarks/tick.py --json out.json

What is timed (see benchmarks/README.md): one control tick = kinematics + constraint rows + QP assembly +
DAQP solve (+ the least-violation machinery's checks), i.e. one call of the task's step Function:

- interpreted : the step Function evaluated by CasADi's VM (vfdsl.compile(task, backend="interpreted")),
                raw call: inputs written into the bound arrays, then BufferedFunction.evaluate();
- generated   : the same Function as generated C (backend="native"), same raw call;
- one level   : the same task solved as one level (its levels' costs summed, one DAQP solve; generated C,
                same raw call): the baseline of the priority levels, which DAQP solves in one
                hierarchical call;
- step()      : the full Controller.step(q, inputs) API on the generated path (input checks, copy of dq);
- pink        : pink.solve_ik, DAQP (qpsolvers), default limits, on two jobs: the Panda with one FrameTask (6 cost rows,
                no constraint rows: the baseline of the targets), and a job close to experiment B's (shr7 at B's
                states: hold the pivot, track B's orientation, damping, a +-1 um PositionBarrier); every ratio is
                printed with the job it is against.

Section 7 times B's step() in every documented call form (positional and keyword dt and params, inputs as a dict
of arrays, lists or tuples), each as a ratio to the fastest.

Each figure is time.perf_counter_ns around one call, after 1,000 warm-up ticks, with the garbage collector
disabled, over states of a closed-loop trajectory recorded beforehand (same states for every variant). The
variants of sections 2 and 3 (every task's and pink's) are timed in turns of 250 ticks, as are those of
sections 6 and 7, so that a burst of load on the shared machine falls on all of them alike.
Progress goes to stderr; the report goes to stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl import pipeline
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus

from tick_jobs import (ROWS_TASK, SWEEP_FULL, SWEEP_QUICK, TASKS, VESSEL_TASK, follow_circle, load_panda_track,
                       panda_tip_error, pink_figures, pink_pivot_ticks, pink_ticks, push_along_curve,
                       slide_on_polytope, twist_about_cone)
from tick_timing import (BLOCK, WARMUP, interleaved, log, machine, one_level, raw_generated, raw_ticks, record,
                         stats, step_ticks, time_raw)

TARGETS = {  # (what, limit in us) per experiment, checked against the generated paths
    "paper_b_virtual_rcm": [("median", 10.0), ("p99", 30.0)],
    "paper_a_follow_curve": [("median", 20.0)],
}
PINK_JOBS = {"frame_task": "frame task (Panda)", "pivot": "pivot (shr7, B-like)"}
PINK_RATIOS = (  # (task, vfdsl path, pink job) of section 3's ratios: the like-for-like pairs first
    ("panda_track", "generated", "frame_task"), ("panda_track", "step", "frame_task"),
    ("paper_b_virtual_rcm", "generated", "pivot"), ("paper_b_virtual_rcm", "step", "pivot"),
    ("paper_b_virtual_rcm", "generated", "frame_task"), ("paper_b_virtual_rcm", "step", "frame_task"),
    ("paper_a_follow_curve", "generated", "frame_task"), ("paper_a_follow_curve", "step", "frame_task"))
PINK_RATIO_TARGET = 20.0
B_PINK_RATIO_TARGET = 25.0    # experiment B's step() against pink's solve_ik on the Panda frame task (a lighter job)
LEVELS_RATIO_TARGET = 1.2     # experiment B's generated tick with its levels / the same task as one level, median
STEP_RATIO_TARGET = 1.3       # Controller.step() / bare generated call, median
ROWS_TARGET = (1000, 150.0)
COMPILE_TARGET = 10.0
PARAMS_RATIO_TARGET = 2.0     # step() with params updated every tick / step() without, median
FORMS_RATIO_TARGET = 1.2      # each documented call form of step() / the fastest form, median (section 7)


# --------------------------------------------------------------------------------------- sections
VARIANTS = ("interpreted", "one_level", "generated", "step")


def experiment(name: str, task, driver, record_ticks: int, cache: Path) -> tuple[dict, dict]:
    """(figures so far, timers): the task's controllers built and its closed-loop states recorded; one timer per
    variant of :data:`VARIANTS` (timed together with the others' by :func:`timed_experiments`)."""
    log(f"[{name}] building generated and interpreted controllers")
    native, library = pipeline.build(task, backend="native", cache_dir=cache)
    interpreted = vfdsl.compile(task, backend="interpreted")
    dt = task.scene.period
    qs, us, dicts, rec_status = record(native, task.start, driver, dt, record_ticks)
    p = native.assembled.context.layout.defaults
    statuses: dict[int, int] = {}
    timers = {"interpreted": raw_ticks(interpreted._runner._function, qs, us, p, dt, {}),
              "one_level": raw_ticks(one_level(task, cache), qs, us, p, dt, {}),
              "generated": raw_ticks(raw_generated(task, library), qs, us, p, dt, statuses),
              "step": step_ticks(native, qs, dicts, dt)}
    return {"rows": len(native.row_labels), "nq": native.nq, "dt": dt, "levels": len(native.assembled.levels),
            "_statuses": statuses,
            "recorded_statuses": {StepStatus(s).name or str(s): c for s, c in rec_status.items()},
            "_states": (qs, dicts)}, timers


def timed_experiments(exps: dict, timers: dict, pink_timers: dict, ticks: int) -> dict:
    """Every experiment's variants and pink's jobs timed together (:func:`interleaved`); the experiments' figures
    filled in, each pink job's ticks returned by name."""
    everything = {(name, variant): timer for name, of_task in timers.items() for variant, timer in of_task.items()}
    everything.update({("pink", job): timer for job, timer in pink_timers.items()})
    log(f"[timing] {len(everything)} variants ({', '.join(timers)}, pink: {', '.join(pink_timers)}), {ticks} ticks "
        f"each, in turns of {BLOCK}")
    samples = interleaved(everything, ticks)
    for name, e in exps.items():
        for variant in VARIANTS:
            e[variant] = stats(samples[(name, variant)])
        statuses = e.pop("_statuses")
        e["optimal_fraction"] = statuses.get(int(StepStatus.OPTIMAL), 0) / ticks
        e["statuses"] = {StepStatus(s).name or str(s): c for s, c in statuses.items()}
    return {job: samples[("pink", job)] for job in pink_timers}


def params_section(exps: dict, ticks: int, cache: Path) -> dict:
    """Section 6: B with its pivot re-registered every tick (1 um circle), as an array and as a list, and a
    20-point run-time curve moved every tick (a 0.25 Hz, 2 mm breathing), against the same states without."""
    out = {}
    task = vfdsl.load(TASKS / "paper_b_virtual_rcm.vf")
    native, _ = pipeline.build(task, backend="native", cache_dir=cache)
    qs, dicts = exps["paper_b_virtual_rcm"]["_states"]
    dt = task.scene.period
    pivot0 = np.array(task.param("pivot").value.xyz)
    array = {"pivot": pivot0.copy()}
    listed = {"pivot": pivot0.tolist()}

    def move_array(k):
        array["pivot"][0] = pivot0[0] + 1e-6 * np.cos(0.01 * k)

    def move_list(k):
        listed["pivot"] = [pivot0[0] + 1e-6 * np.cos(0.01 * k), pivot0[1], pivot0[2]]
    timers = {("B pivot", "without"): step_ticks(native, qs, dicts, dt),
              ("B pivot", "array"): step_ticks(native, qs, dicts, dt, array, move_array),
              ("B pivot", "list"): step_ticks(native, qs, dicts, dt, listed, move_list)}
    s = np.linspace(0, 1, 20)
    vessel0 = np.column_stack([0.06 * (s - 0.5), 0.004 * np.sin(3 * s), np.full(20, 0.28)])
    vessel_task_path = cache / "vessel_20.vf"
    vessel_task_path.write_text(VESSEL_TASK.format(points=", ".join(f"[{x!r}, {y!r}, {z!r}]" for x, y, z in vessel0.tolist())))
    vessel = vfdsl.load(vessel_task_path)
    ctrl, _ = pipeline.build(vessel, backend="native", cache_dir=cache)
    start = np.array(task.start, dtype=float)
    moving = {"vessel": vessel0.copy()}

    def breathe(k):
        moving["vessel"][:, 2] = vessel0[:, 2] + 0.002 * np.sin(2 * np.pi * 0.25 * k * dt)

    def drive(k, q):
        return {"f": np.array([2.0 * np.cos(0.002 * k), 0.5, 0.0])}

    def drive_breathing(k, q):
        breathe(k)
        return drive(k, q)
    still_qs, _, still_dicts, _ = record(ctrl, start, drive, dt, 4_000, None)
    vqs, _, vdicts, _ = record(ctrl, start, drive_breathing, dt, 4_000, moving)   # closed loop on the moving curve
    timers[("curve 20 points", "without")] = step_ticks(ctrl, still_qs, still_dicts, dt)
    timers[("curve 20 points", "array")] = step_ticks(ctrl, vqs, vdicts, dt, moving, breathe)
    log(f"[params] B with a re-registered pivot, and a 20-point run-time curve moved every tick ({ticks} ticks "
        f"each, in turns)")
    for (name, variant), ns in interleaved(timers, ticks).items():
        out.setdefault(name, {})[variant] = stats(ns)
    return out


def call_forms_section(exps: dict, ticks: int, cache: Path) -> dict:
    """Section 7: experiment B's step() in every documented call form, on B's recorded states, timed in turns. Each
    form's q and inputs are written into the caller's own objects before the tick (outside the timed region, as
    :func:`step_ticks`): arrays and lists in place, a new tuple per tick; ``params`` is B's pivot as an array."""
    task = vfdsl.load(TASKS / "paper_b_virtual_rcm.vf")
    ctrl, _ = pipeline.build(task, backend="native", cache_dir=cache)
    qs, dicts = exps["paper_b_virtual_rcm"]["_states"]
    step, pc, m, dt = ctrl.step, time.perf_counter_ns, len(qs), task.scene.period
    q = np.empty(qs.shape[1])
    arrays = {"tau": np.empty(3)}
    lists = {"tau": [0.0, 0.0, 0.0]}
    tuples = {"tau": (0.0, 0.0, 0.0)}
    params = {"pivot": np.array(task.param("pivot").value.xyz)}

    def load(k: int) -> np.ndarray:
        i = k % m
        q[:] = qs[i]
        arrays["tau"][:] = dicts[i]["tau"]
        return dicts[i]["tau"]

    def positional(k):
        load(k)
        t0 = pc()
        step(q, arrays)
        return pc() - t0

    def dt_positional(k):
        load(k)
        t0 = pc()
        step(q, arrays, None, dt)
        return pc() - t0

    def dt_keyword(k):
        load(k)
        t0 = pc()
        step(q, arrays, dt=dt)
        return pc() - t0

    def params_positional(k):
        load(k)
        t0 = pc()
        step(q, arrays, params, dt)
        return pc() - t0

    def params_keyword(k):
        load(k)
        t0 = pc()
        step(q, arrays, params=params)
        return pc() - t0

    def of_lists(k):
        lists["tau"][:] = load(k).tolist()
        t0 = pc()
        step(q, lists, None, dt)
        return pc() - t0

    def of_tuples(k):
        tuples["tau"] = tuple(load(k).tolist())
        t0 = pc()
        step(q, tuples, None, dt)
        return pc() - t0
    timers = {"step(q, inputs)": positional, "step(q, inputs, None, dt)": dt_positional,
              "step(q, inputs, dt=dt)": dt_keyword, "step(q, inputs, params, dt)": params_positional,
              "step(q, inputs, params=params)": params_keyword, "inputs a dict of lists": of_lists,
              "inputs a dict of tuples": of_tuples}
    log(f"[call forms] B's step() in {len(timers)} call forms ({ticks} ticks each, in turns)")
    return {form: stats(ns) for form, ns in interleaved(timers, ticks).items()}


def sweep(ns, ticks: int, tmp: Path) -> list[dict]:
    robot = Robot.load("shr7")
    start = vfdsl.load(TASKS / "paper_b_virtual_rcm.vf").start      # experiment B's start: tip 10 mm below the RCM
    tip, _ = robot.frame_pose(start, "tool_tip")
    results = []
    for n in ns:
        folder = tmp / f"rows_{n}"
        folder.mkdir()
        path = folder / f"rows_{n}x{n}.vf"
        path.write_text(ROWS_TASK.format(n=n))
        task = vfdsl.load(path)
        log(f"[rows {n}x{n}] compiling")
        t0 = time.perf_counter()
        ctrl, lib = pipeline.build(task, backend="native", cache_dir=folder / "cache")
        compile_s = time.perf_counter() - t0
        c_mb = lib.c_path.stat().st_size / 1e6
        p = ctrl.param_vector({"p": tip})           # the polytope centred on the tip at the start
        qs, us, _, _ = record(ctrl, start, slide_on_polytope, 0.01, 400, params={"p": tip})
        log(f"[rows {n}x{n}] {len(ctrl.row_labels)} rows, compiled in {compile_s:.1f} s; timing")
        timing, statuses = time_raw(raw_generated(task, lib), qs, us, p, 0.01, ticks)
        results.append({"n": n, "rows": len(ctrl.row_labels), "compile_s": compile_s, "c_source_mb": c_mb,
                        **timing,
                        "optimal_fraction": statuses.get(0, 0) / ticks})
    return sorted(results, key=lambda r: r["rows"])


def compile_times(paths, tmp: Path) -> list[dict]:
    results = []
    for path in paths:
        task = vfdsl.load(path)
        cache = Path(tempfile.mkdtemp(dir=tmp, prefix="compile-"))
        log(f"[compile] {path.name}")
        t0 = time.perf_counter()
        ctrl, lib = pipeline.build(task, backend="native", cache_dir=cache)
        fresh = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, again = pipeline.build(task, backend="native", cache_dir=cache)
        cached = time.perf_counter() - t0
        assert again.reused, f"{path.name}: the second build did not hit the cache"
        results.append({"task": path.stem, "rows": len(ctrl.row_labels), "fresh_s": fresh, "cached_s": cached,
                        "c_source_mb": lib.c_path.stat().st_size / 1e6})
    return results


# ------------------------------------------------------------------------------------------- report
def verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def report(m: dict, exps: dict, pink: dict, rows: list[dict], compiles: list[dict], params: dict, forms: dict,
           quick: bool, elapsed: float) -> str:
    out = []
    w = out.append
    w("vfdsl tick benchmark" + ("  (--quick: fewer ticks, smaller sweep)" if quick else ""))
    w("=" * 100)
    w("1. Machine")
    w("-" * 100)
    w(f"CPU        {m['cpu']}, {m['cores']} cores ({m['cores_usable']} usable); Linux {m['kernel']}; "
      f"load average {m['loadavg']:.2f} at start")
    w(f"Python     {m['python']}")
    w(f"packages   numpy {m['numpy']}, casadi {m['casadi']}, pinocchio {m['pinocchio']}, pink {m['pink']}, "
      f"daqp {m['daqp']}, qpsolvers {m['qpsolvers']}, vfdsl {m['vfdsl']}")
    w(f"cc         {m['cc']}")
    w(f"timing     perf_counter_ns per call (its own overhead {m['timer_overhead_ns']:.0f} ns, included), "
      f"{WARMUP} warm-up ticks, gc disabled; variants timed in turns of {BLOCK} ticks")

    w("")
    w("2. Tick time, shr7 paper experiments and the Panda task (us; closed-loop states, user-like inputs)")
    w("-" * 100)
    w(f"{'task':<22}{'rows':>5}  {'path':<13}{'median':>8}{'p99':>9}{'max':>9}   {'ticks':>6}   targets")
    for name, e in exps.items():
        label = {"paper_a_follow_curve": "A  follow curve", "paper_b_virtual_rcm": "B  virtual RCM",
                 "panda_track": "panda_track"}[name]
        for i, kind in enumerate(("interpreted", "one_level", "generated", "step")):
            s = e[kind]
            checks = []
            if kind in ("generated", "step"):
                for what, limit in TARGETS.get(name, []):
                    value = s["median_us" if what == "median" else "p99_us"]
                    checks.append(f"{what} <= {limit:g}: {verdict(value <= limit)}")
            path = {"interpreted": "interpreted", "one_level": "one level", "generated": "generated",
                    "step": "step() API"}[kind]
            n_rows = (str(e["rows"]) if e["rows"] else "0*") if i == 0 else ""
            w(f"{label if i == 0 else '':<22}{n_rows:>5}  {path:<13}"
              f"{s['median_us']:8.2f}{s['p99_us']:9.2f}{s['max_us']:9.1f}   {s['ticks']:>6}   "
              + ",  ".join(checks))
        w(f"{'':<29}speed-up generated vs interpreted {e['interpreted']['median_us'] / e['generated']['median_us']:.1f}x;"
          f" {e['levels'] or 1} levels / one level {e['generated']['median_us'] / e['one_level']['median_us']:.2f}"
          + (f" (target <= {LEVELS_RATIO_TARGET:g}: "
             f"{verdict(e['generated']['median_us'] / e['one_level']['median_us'] <= LEVELS_RATIO_TARGET)});"
             if name == "paper_b_virtual_rcm" else ";") +
          f" step() adds {e['step']['median_us'] - e['generated']['median_us']:.2f} us"
          f" (step()/generated {e['step']['median_us'] / e['generated']['median_us']:.2f},"
          f" target <= {STEP_RATIO_TARGET:g}: {verdict(e['step']['median_us'] / e['generated']['median_us'] <= STEP_RATIO_TARGET)});"
          f" optimal ticks {100 * e['optimal_fraction']:.1f}%")

    w(f"{'':<29}* panda_track has no general rows, only variable bounds (joint limits and speeds)")
    w("")
    w("3. pink, two jobs (dt 10 ms, solver daqp through qpsolvers, pink's default limits; in turns with section 2)")
    w("-" * 100)
    w("frame task: the Panda, one FrameTask on tool_tip (6 cost rows, no constraint rows), a target on a 20 mm circle")
    w("pivot:      shr7 at experiment B's recorded states, a job close to B's: a FrameTask holding the pivot")
    w("            (position cost 100) and tracking B's next orientation (cost 1), a DampingTask, a PositionBarrier")
    w("            of +-1 um about the pivot (6 rows); no counterpart of B's 15 deg cone (pink has no cone barrier)")
    w(f"{'':<56}{'median':>8}{'p99':>9}{'max':>9}   {'ticks':>6}")
    for job, update in (("frame_task", "solve_ik + integrate + update"), ("pivot", "solve_ik + update")):
        for key, what in (("solve_ik", "solve_ik"), ("solve_ik_plus_update", update)):
            s = pink[job][key]
            w(f"{'pink ' + PINK_JOBS[job] + ', ' + what:<56}{s['median_us']:8.2f}{s['p99_us']:9.2f}"
              f"{s['max_us']:9.1f}   {s['ticks']:>6}")
    pt = exps["panda_track"]
    w(f"frame task: tip distance from the moving target, max: pink {1e3 * pink['frame_task']['tip_error_mm']:.1f} um "
      f"(pose feedback); vfdsl panda_track {1e3 * pt['tip_error_mm']:.0f} um")
    w("(the vfdsl task integrates the target's twist without pose feedback: it drifts, as expected)")
    w(f"pivot: tip distance from the pivot after pink's step, max {1e3 * pink['pivot']['tip_error_mm']:.2f} um")
    w("")
    w(f"{'ratio pink solve_ik / vfdsl':<36}{'against pink':<22}{'median':>8}{'p99':>8}   target")
    for name, kind, job in PINK_RATIOS:
        ps, e = pink[job]["solve_ik"], exps[name]
        rm = ps["median_us"] / e[kind]["median_us"]
        r99 = ps["p99_us"] / e[kind]["p99_us"]
        target = ""
        if name == "panda_track" and kind == "generated":
            target = f"median >= {PINK_RATIO_TARGET:g}x: {verdict(rm >= PINK_RATIO_TARGET)}"
        elif name == "paper_b_virtual_rcm" and kind == "step" and job == "frame_task":
            target = (f"median >= {B_PINK_RATIO_TARGET:g}x: {verdict(rm >= B_PINK_RATIO_TARGET)} "
                      f"(a lighter job than B's)")
        elif name != "panda_track" and job == "frame_task":
            target = "(reference: different robot and task)"
        path = {"generated": "generated", "step": "step() API"}[kind]
        w(f"{'  ' + name + ', ' + path:<36}{PINK_JOBS[job]:<22}{rm:7.1f}x{r99:7.1f}x   {target}")
    w("4. Scaling with the number of rows: shr7, require tip stays_at(p) within 1 um resolution NxN "
      "(generated, feasible states)")
    w("-" * 100)
    closest = min(rows, key=lambda r: abs(r["rows"] - ROWS_TARGET[0]))
    w(f"{'N x N':>7}{'rows':>7}{'median':>9}{'p99':>9}{'max':>9}{'compile s':>11}{'C MB':>7}"
      f"{'optimal':>9}   target")
    for r in rows:
        target = ""
        if r is closest and abs(r["rows"] - ROWS_TARGET[0]) > 0.25 * ROWS_TARGET[0]:
            target = f"(no row count near {ROWS_TARGET[0]:,}: target not checked)"
        elif r is closest:
            target = (f"{ROWS_TARGET[0]:,} rows: median <= {ROWS_TARGET[1]:g} us: "
                      f"{verdict(r['median_us'] <= ROWS_TARGET[1])}")
        w(f"{str(r['n']) + 'x' + str(r['n']):>7}{r['rows']:>7}{r['median_us']:9.1f}{r['p99_us']:9.1f}"
          f"{r['max_us']:9.1f}{r['compile_s']:11.1f}{r['c_source_mb']:7.1f}{100 * r['optimal_fraction']:8.0f}%   {target}")
    w(f"{'':>7}sweep compile total {sum(r['compile_s'] for r in rows):.0f} s; "
      f"{rows[0]['ticks']} ticks per row count")

    w("")
    w("5. Compile time per example task (fresh cache directory each; then a cached rebuild)")
    w("-" * 100)
    w(f"{'task':<34}{'rows':>5}{'fresh s':>9}{'cached s':>10}{'C MB':>7}   target")
    for c in compiles:
        w(f"{c['task']:<34}{c['rows']:>5}{c['fresh_s']:9.2f}{c['cached_s']:10.2f}{c['c_source_mb']:7.2f}   "
          f"fresh <= {COMPILE_TARGET:g} s: {verdict(c['fresh_s'] <= COMPILE_TARGET)}")
    w("")
    w("6. Run-time params: step() with params changed every tick, against step() on the same states without")
    w("-" * 100)
    w(f"{'task':<22}{'params':<24}{'median':>8}{'p99':>9}{'max':>9}   ratio to without (median)")
    for name, variants in params.items():
        base = variants["without"]["median_us"]
        for kind, v in variants.items():
            ratio = v["median_us"] / base
            target = "" if kind == "without" else (f"{ratio:.2f}  target <= {PARAMS_RATIO_TARGET:g}: "
                                                   f"{verdict(ratio <= PARAMS_RATIO_TARGET)}")
            what = {"without": "none (defaults)", "array": "preallocated arrays", "list": "a new list"}[kind]
            w(f"{name:<22}{what:<24}{v['median_us']:8.2f}{v['p99_us']:9.2f}{v['max_us']:9.1f}   {target}")
    w("")
    w("7. Call forms of Controller.step on experiment B (q and inputs the caller's; dict of arrays unless said)")
    w("-" * 100)
    fastest = min(f["median_us"] for f in forms.values())
    w(f"{'form':<36}{'median':>8}{'p99':>9}{'max':>9}   ratio to the fastest (median)")
    for form, f in forms.items():
        ratio = f["median_us"] / fastest
        w(f"{form:<36}{f['median_us']:8.2f}{f['p99_us']:9.2f}{f['max_us']:9.1f}   {ratio:.2f}  "
          f"target <= {FORMS_RATIO_TARGET:g}: {verdict(ratio <= FORMS_RATIO_TARGET)}")
    w("")
    w(f"total run time {elapsed:.0f} s")
    return "\n".join(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short run: fewer ticks, smaller row sweep")
    parser.add_argument("--json", metavar="FILE", help="also save the numbers as JSON")
    args = parser.parse_args(argv)
    ticks = 3_000 if args.quick else 20_000
    sweep_ticks = 1_000 if args.quick else 5_000
    started = time.perf_counter()

    m = machine()
    with tempfile.TemporaryDirectory(prefix="vfdsl-bench-") as tmp_name:
        tmp = Path(tmp_name)
        cache = tmp / "cache"
        exps, timers = {}, {}
        for name, driver in (("paper_a_follow_curve", push_along_curve), ("paper_b_virtual_rcm", twist_about_cone)):
            task = vfdsl.load(TASKS / f"{name}.vf")
            exps[name], timers[name] = experiment(name, task, driver(task), 4_000, cache)
        panda = load_panda_track()
        exps["panda_track"], timers["panda_track"] = experiment("panda_track", panda, follow_circle(panda.scene.period),
                                                                4_000, cache)
        exps["panda_track"]["tip_error_mm"] = panda_tip_error(panda, exps["panda_track"]["_states"],
                                                              panda.scene.period)
        b = vfdsl.load(TASKS / "paper_b_virtual_rcm.vf")
        errors: dict = {"frame_task": [], "pivot": []}
        pink_ns = timed_experiments(exps, timers, {
            "frame_task": pink_ticks(0.01, errors["frame_task"]),
            "pivot": pink_pivot_ticks(b, exps["paper_b_virtual_rcm"]["_states"][0], errors["pivot"])}, ticks)
        pink = {job: pink_figures(ns, errors[job]) for job, ns in pink_ns.items()}
        params = params_section(exps, ticks, cache)
        forms = call_forms_section(exps, ticks, cache)
        rows = sweep(SWEEP_QUICK if args.quick else SWEEP_FULL, sweep_ticks, tmp)
        compiles = compile_times(sorted(TASKS.glob("*.vf")), tmp)
    for e in exps.values():
        e.pop("_states")

    elapsed = time.perf_counter() - started
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": m, "quick": args.quick, "experiments": exps,
                                               "pink": pink, "rows_sweep": rows, "compile": compiles,
                                               "params": params, "call_forms": forms,
                                               "elapsed_s": elapsed}, indent=2))
    print(report(m, exps, pink, rows, compiles, params, forms, args.quick, elapsed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
