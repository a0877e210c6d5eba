"""``vfdsl simulate``: the command's options, and what it does with them."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from tqdm import tqdm

import vfdsl
from vfdsl.errors import VfError
from vfdsl.files import check_outputs, check_writable, path_argument, task_sources
from vfdsl import limits
from vfdsl.ir import captures
from vfdsl.runtime.values import ASSUMED_PERIOD, dt_range
from vfdsl.sim.mcap_trace import write_mcap
from vfdsl.sim.recording import late_inputs, recording_text
from vfdsl.sim.operator import teleop_table
from vfdsl.sim import report, trace
from vfdsl.sim.cluster import connect
from vfdsl.sim.metrics import metric_defs
from vfdsl.sim.runner import default_workers, loaded, make_jobs, run, start_configuration
from vfdsl.sim.scene_file import default_scene, load_settings, parse_setting
from vfdsl.sim.scripted import late_events
from vfdsl.sim.settings import GRID_NAMES, SHOWN_IN, check_setting, check_ticks

DESCRIPTION = """\
Run a task's controller in closed loop on a simulated robot (Pinocchio kinematics, with optional
latency, servo lag, joint resolution) pushed by a simulated hand (with tremor and drift), and score
it: each constraint's error in mm or deg, by the robot's exact kinematics and, with tracker noise, by a
simulated optical tracker. Settings come from the simulation scene <task>.sim.yaml next to the task
(or --scene); the options below override it. The scene's format, with an example of every kind, is in
docs/simulate.md (JSON Schema: docs/simulate.schema.json)."""

EPILOG = """\
examples:
  vfdsl simulate tasks/paper_b_virtual_rcm.vf                      paper experiment B, 5 trials
  vfdsl simulate tasks/paper_a_follow_curve.vf --plot a.png        paper experiment A, like Fig. 6
  vfdsl simulate tasks/paper_a_follow_curve.vf --grid period=150ms,40ms,10ms,1ms --trials 1 \\
      --latency 0 --noise 0 --plot fig7.png                         the loop-period study (Fig. 7)
  vfdsl simulate tasks/paper_a_follow_curve.vf --scene tasks/paper_a_plate_moves.sim.yaml \\
      --plot fig8.png                                               the plate moves and tilts (Fig. 8)
  vfdsl simulate tasks/lecture_remote_center.vf --duration 5s      any task: a generic hand
  vfdsl simulate tasks/paper_b_virtual_rcm.vf --trials 1000 --duration 1s --cluster tcp://host:8786

limits (exit status 2 before any work; docs/language.md, "Limits"): at most 1,000,000 ticks per trial
(duration / period) and 20,000,000 in a run, a period of 0.01 ms at least and within [P / 100, 10 x P] of
the task scene's period P (the controller's dt range), 100,000 trials, 1,000 grid
points; --workers is capped at the trials and the cores; --cluster must be an address (tcp://host:8786) and
answer as a Dask scheduler within 10 s; the output files are checked writable before the run, and refused
when one is a file the run reads (the task, its scenes, its imports) or two name the same file.

Values take units (10ms, 0.2mm); bare numbers are SI. --json writes every metric by name
(metrics.<name>.mean / std / max) with the settings and the seed; --csv one row per trial; --trace
one row per tick per trial (.csv or .parquet, SI units). The same seed gives the same numbers, whatever
runs the trials. The scene format, the trace's columns and the defaults: docs/simulate.md."""


def add_parser(commands) -> None:
    p = commands.add_parser("simulate", help="run a task on a simulated robot and hand, and measure its errors",
                            description=DESCRIPTION, epilog=EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", type=path_argument, help="the .vf task file")
    p.add_argument("--scene", metavar="S.yaml", type=path_argument,
                   help="simulation scene (default: <task>.sim.yaml if it exists)")
    p.add_argument("--duration", metavar="T", help="simulated time per trial (e.g. 60s)")
    p.add_argument("--period", metavar="DT", help="control period (e.g. 10ms; default: the scene's; within 1/100 to 10 "
                                                   "times the task scene's period)")
    p.add_argument("--latency", metavar="L", help="command latency (e.g. 140ms; at most 10s)")
    p.add_argument("--servo-lag", metavar="T", help="first-order servo time constant (e.g. 5ms; at most 10s)")
    p.add_argument("--resolution", choices=("off", "robot"), help="joint resolution: robot = the URDF sidecar's")
    p.add_argument("--noise", metavar="RMS", help="tracker noise, 3-D RMS per marker (e.g. 0.2mm)")
    p.add_argument("--trials", type=int, metavar="N", help="trials per setting (seeds K, K+1, ...)")
    p.add_argument("--seed", type=int, metavar="K", help="seed of the first trial")
    p.add_argument("--grid", action="append", metavar="NAME=V1,V2,...", default=[],
                   help=f"sweep a setting ({', '.join(GRID_NAMES)}); repeat for a product")
    p.add_argument("--workers", type=int, metavar="N",
                   help="local processes (default: all cores for long runs, else 1; at most one per trial "
                        "and per core)")
    p.add_argument("--cluster", metavar="ADDRESS",
                   help="run the trials on the Dask distributed scheduler at this address (e.g. tcp://host:8786)")
    p.add_argument("--json", metavar="OUT.json", type=path_argument,
                   help="write every metric, the settings and the seeds")
    p.add_argument("--csv", metavar="OUT.csv", type=path_argument,
                   help="write one row per trial (settings, seed, metrics)")
    p.add_argument("--plot", type=path_argument, metavar="OUT.png", help="write a plot of the first trial (PNG)")
    p.add_argument("--trace", type=path_argument, metavar="OUT.csv|OUT.parquet|OUT.mcap",
                   help="write every tick of every trial: time, q, dq, inputs, params, status, violations, metrics "
                        "(SI units; columns in docs/simulate.md)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    p.set_defaults(run=main)


def _overrides(args: argparse.Namespace) -> dict:
    out = {}
    for name in ("duration", "period", "latency", "servo_lag", "noise", "resolution"):
        text = getattr(args, name)
        if text is not None:
            out[name] = _option(name, text)
    for name in ("trials", "seed"):
        value = getattr(args, name)
        if value is not None:
            try:
                check_setting(name, value)
            except VfError as err:
                raise VfError(f"--{name} {value}: {err.message}", hint=err.hint) from None
            out[name] = value
    return out


def _option(name: str, text: str, option: str | None = None):
    try:
        return parse_setting(name, text)
    except VfError as err:
        label = f"{option}{text}" if option else f"--{name.replace('_', '-')} {text}"
        raise VfError(f"{label}: {err.message}", hint=err.hint) from None


def _grid(specs: list[str]) -> list[tuple[str, list]]:
    grid = []
    for spec in specs:
        name, sep, values = spec.partition("=")
        name = name.strip().replace("-", "_")
        if not sep or not values.strip():
            raise VfError(f"--grid {spec}: write NAME=V1,V2,..., like period=150ms,40ms")
        if name in dict(grid):
            raise VfError(f"--grid {spec}: '{name}' is swept twice")
        grid.append((name, [_option(name, v, f"--grid {name}=") for v in values.split(",")]))
    return grid


def main(args: argparse.Namespace) -> int:
    task = vfdsl.load(args.file)
    scene = args.scene or default_scene(args.file)
    settings = load_settings(task, scene)
    settings = settings.replace(**_overrides(args))
    grid = _grid(args.grid)
    if args.workers is not None and args.workers < 1:
        raise VfError(f"--workers must be at least 1, got {args.workers}")
    if args.trace:
        trace.check_path(args.trace)
    check_outputs({"--json": args.json, "--csv": args.csv, "--trace": args.trace, "--plot": args.plot},
                  [*task_sources(task), ("the simulation scene", scene),
                   ("the scene's recording", settings.recording and settings.recording.bag)])
    _check_work(settings, grid, task)
    start_configuration(task, settings)
    for warning in _events_after_the_end(settings, grid):
        print(warning.render("warning"), file=sys.stderr)
    for name in (args.json, args.csv, args.trace):
        if name:
            _check_writable(name)
    if args.plot:
        _check_writable(args.plot, plot=True)
    client = connect(args.cluster) if args.cluster is not None else None   # before any work: a wrong address fails
    try:
        jobs = make_jobs(args.file, settings, grid, keep_series=bool(args.plot), keep_trace=bool(args.trace))
        ctx = loaded(args.file)                 # compile (or load from the cache) once, here, before workers
        workers = min(args.workers, len(jobs), os.cpu_count() or 1) if args.workers else default_workers(jobs)
        total = sum(max(1, round(j.settings.duration / j.settings.period)) for j in jobs)
        start = time.perf_counter()
        with tqdm(total=total, unit="tick", unit_scale=True, delay=1.0, disable=True if args.quiet else None,
                  leave=False, file=sys.stderr) as bar:
            results = run(jobs, workers=workers, cluster=client, progress=bar.update)
    finally:
        if client is not None:
            client.close()
    seconds = time.perf_counter() - start
    doc = report.document(task.name, str(args.file), settings, results, grid)
    tolerances = {d.name: d.tolerance for d in metric_defs(captures.as_params(task), ctx.robot, settings.metrics)
                  if d.tolerance is not None}
    if not args.quiet:
        simulated = sum(r.ticks for r in results) * settings.period if not grid else None
        print(_heading(task.name, settings, doc, len(jobs), seconds, simulated))
        print(report.table(doc, tolerances))
        if "procedure" in doc:
            print("\n" + report.phase_table(doc))
        if "teleop" in doc:
            print("\nteleoperation (error to the scaled command and force in free motion: followed, no fixture "
                  "acting)\n" + teleop_table(doc))
        if doc["fallback_ticks"]:
            print(f"\n{doc['fallback_ticks']} of {doc['ticks']} ticks needed the least-violation fallback")
        if doc["uncertified_ticks"]:
            print(f"\n{doc['uncertified_ticks']} of {doc['ticks']} ticks found no certificate that their priority "
                  "levels are exact (status UNCERTIFIED: DAQP's answer, to its tolerance; docs/runtime.md)")
    if args.json:
        _write(args.json, lambda path: path.write_text(report.to_json(doc)))
    if args.csv:
        _write(args.csv, lambda path: path.write_text(report.to_csv(doc)))
    if args.trace:
        if Path(args.trace).suffix.lower() == ".mcap":
            _write(args.trace, lambda path: write_mcap(path, results, task))
        else:
            _write(args.trace, lambda path: trace.write(path, results, task.name, str(args.file)))
    if args.plot:
        from vfdsl.sim.plots import plot_run
        _write(args.plot, lambda path: plot_run(task, settings, results, grid, str(path)))
    return 0


def _events_after_the_end(settings, grid: list[tuple[str, list]]) -> list[VfError]:
    """A warning for each disturbance, step, ramp, push, button press or recorded input of the scene that starts at or
    after the end of the run (the longest ``duration`` of the grid): it never happens (a run shortened with
    --duration, a mistyped time, a topic stamped by another clock)."""
    end = max(dict(grid).get("duration", [settings.duration]))
    events = [(d.at, f"the {d.kind} disturbance at {d.at:g} s", d.where) for d in settings.disturbances]
    starts = [(m.at if m.kind == "step" else m.start, m) for m in settings.motions if m.kind in ("step", "ramp")]
    events += [(t, f"the {m.kind} motion of param '{m.param}' (from {t:g} s)", m.where) for t, m in starts]
    events += late_events(settings, end)
    events += late_inputs(settings.recording, end) if settings.recording is not None else []
    return [VfError(f"{what} starts after the run's {end:g} s: it does not happen in this run", where,
                    hint="lengthen the run (--duration, or duration in the scene) or move the event earlier")
            for t, what, where in events if t >= end - 1e-12]


def _check_work(settings, grid: list[tuple[str, list]], task) -> None:
    """Refuse a run beyond the limits of vfdsl/limits.py before any work starts: ticks per trial (at
    every grid point), grid points, and ticks of the whole run; and a period the task's controller does not step
    with (:func:`vfdsl.runtime.values.dt_range`)."""
    points: list[dict] = [{}]
    for name, values in grid:
        if len(points) * len(values) > limits.GRID_POINTS:
            raise limits.exceeded("the --grid sweep has too many settings", limits.GRID_POINTS, None,
                                  hint="sweep fewer values, or run the sweep in parts")
        points = [{**p, name: v} for p in points for v in values]
    total = 0
    for point in points:
        duration, period = point.get("duration", settings.duration), point.get("period", settings.period)
        where = " ".join(f"--grid {k}={v:g}" if isinstance(v, float) else f"--grid {k}={v}" for k, v in point.items())
        low, high = dt_range(task.scene.period)
        if not low <= period <= high:
            raise VfError(f"{where + ': ' if where else ''}a period of {period * 1e3:g} ms is outside "
                          f"[{low * 1e3:g} ms, {high * 1e3:g} ms], the periods task '{task.name}' steps at (1/100 to "
                          f"10 times its scene's period, {(task.scene.period or ASSUMED_PERIOD) * 1e3:g} ms)",
                          hint="a loop much faster or slower than that: give it as the `period` of the task's scene")
        total += check_ticks(duration, period, None, f"{where}: " if where else "") * settings.trials
    if total > limits.RUN_TICKS:
        raise limits.exceeded(f"this run is {total:,} control ticks ({settings.trials:,} trial(s) x "
                              f"{len(points):,} setting(s))", limits.RUN_TICKS, None,
                              hint="fewer trials, a shorter duration or a longer period")


def _check_writable(name: str, plot: bool = False) -> None:
    """An output file that can be written (:func:`vfdsl.files.check_writable`, a FIFO without a reader refused
    rather than waited on), and a plot's extension a format matplotlib writes."""
    path = Path(name)
    if plot and path.suffix:
        from matplotlib.backend_bases import FigureCanvasBase
        formats = FigureCanvasBase.get_supported_filetypes()
        if path.suffix[1:].lower() not in formats:
            raise VfError(f"cannot write {name}: matplotlib writes no '{path.suffix}' files",
                          hint="use one of " + ", ".join(f".{f}" for f in sorted(formats)))
    check_writable(path)


def _write(name: str, write) -> None:
    try:
        write(Path(name))
    except OSError as exc:
        raise VfError(f"cannot write {name}: {exc.strerror or exc}") from None


def _heading(name: str, s, doc: dict, trials: int, seconds: float, simulated: float | None) -> str:
    hand = doc["hand"]
    if hand is None and s.recording is not None and (s.recording.inputs or s.recording.joints is not None):
        hand_text = "recorded inputs: " + recording_text(s.recording, s.period)
    elif hand is None:
        if s.operator is not None:
            hand_text = (f"an operator moves master '{s.operator.input}' through {len(s.operator.times)} waypoint(s) "
                         f"over {s.operator.times[-1]:g} s")
        elif doc.get("teleop"):
            hand_text = "no operator (the scene has no operator:): the master rests where it starts"
        else:
            hand_text = "no hand (the task has no tracked input)" if not s.pushes else "no hand: the scene's pushes"
    else:
        unit, factor = SHOWN_IN[hand["dimension"]]
        aim = hand["curve"] or hand["target"] or hand["direction"]
        aim = aim if isinstance(aim, str) else "[" + ", ".join(f"{x:.3g}" for x in aim) + "]"
        hand_text = (f"hand: {hand['kind']} {aim} with input '{hand['input']}', {hand['magnitude'] * factor:.3g} "
                     f"{unit}, tremor {hand['tremor'] * factor:.3g} {unit} RMS, drift {hand['drift'] * factor:.3g} "
                     f"{unit} RMS" + (f"\n  {hand['assumed']}" if hand.get("assumed") else ""))
    if s.pushes or s.presses or s.sensors:
        hand_text += "\nscripted: " + "; ".join(
            [f"{len(s.pushes)} push(es)"] * bool(s.pushes)
            + [f"{sum(p.input == name for p in s.presses)} press(es) of '{name}'"
               for name in dict.fromkeys(p.input for p in s.presses)]
            + [f"sensor noise on '{n.input}' {n.linear:.3g} RMS (SI)"
               + (f", {n.angular:.3g} angular" if n.angular else "") for n in s.sensors])
    moved = doc.get("motion")
    if moved:
        hand_text += (f"\nachieved: the hand moved '{moved['frame']}' {moved['path_mm']:.3g} mm along its path (net "
                      f"{moved['net_mm']:.3g} mm) and turned its tool axis {moved['turn_deg']:.3g} deg"
                      + (f" (mean of {moved['trials']} trials)" if moved["trials"] > 1 else ""))
        fractions = moved.get("commanded_fraction") or {}
        hand_text += ("\n  of the motion the hand commanded, the robot made: "
                      + ", ".join(f"{name} {fraction:.1%}" for name, fraction in fractions.items()) if fractions
                      else "\n  the hand commanded no motion of a tracked part (its input is zero, or no `minimize "
                           "track` reads it)")
    speed = f", {simulated / seconds:.0f}x real time" if simulated else ""
    return (f"{name}: {trials} trial(s) of {s.duration:g} s at a {s.period * 1e3:g} ms period, latency "
            f"{s.latency * 1e3:g} ms, servo lag {s.servo_lag * 1e3:g} ms, resolution {s.resolution}, tracker "
            f"noise {s.noise * 1e3:g} mm RMS; seed {s.seed}\n{hand_text}\n"
            f"({seconds:.2f} s wall{speed}; errors in each constraint's units, pooled over every tick)\n")
