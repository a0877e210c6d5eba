"""Running trials: one closed loop of a task's controller, the simulated robot and the simulated hand, then
its metrics; many trials (and a grid of settings) in this process, a local process pool, or on a Dask
cluster.

One tick at time t = k dt: apply the disturbances due; move the params of the scene's motions (their scene
value plus the displacement at t, written in place into arrays allocated once); read the encoders (q); the
hand's input (aimed at the moved geometry), plus the scene's scripted pushes, button presses and sensor noise
(:mod:`vfdsl.sim.scripted`); dq = controller.step(q, input, params); a procedure's phase, monitors and transitions
(:mod:`vfdsl.sim.phases`); command dq (it arrives after the latency); advance the robot to t + dt.
The metrics are computed afterwards from the encoder readings, by Pinocchio's kinematics, each tick against the
geometry in force at that tick.

Trial i of a run with seed K uses seed K + i (the same in every grid point, so that grid points differ
only by their settings); a trial's seed fixes its hand and its tracker noise, so a run is repeatable.
Compiled controllers cannot be pickled: each worker process builds its own from the task file (the
generated library is cached on disk, so that costs a load, not a compile); each thread of a process gets
its own controller (controllers own their solver memory, so threads run their trials in parallel).
"""

from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.compiler.context import flatten
from vfdsl.errors import VfError
from vfdsl.ir import captures
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus
from vfdsl.sim import trace as tr
from vfdsl.sim import tracker
from vfdsl.sim.cluster import connect
from vfdsl.sim.geometry import Scene
from vfdsl.sim.hand import Hand, generic_hand
from vfdsl.sim.metrics import Stats, errors, frame_poses, metric_defs, prepare_meshes
from vfdsl.objectives.haptics import teleop_terms
from vfdsl.sim.operator import TeleopRecord
from vfdsl.sim.phases import PhaseRecord
from vfdsl.sim.robot import SimRobot
from vfdsl.sim.scripted import ScriptedInputs
from vfdsl.sim.settings import SimSettings, hand_dimension, tracked_frame

PROGRESS_EVERY = 500                 # ticks between progress updates of an in-process trial
SIMULATED = 0.5
"""An in-process trial reports each tick as this much done when simulated, and the rest when scored (its mesh
clearances as they are measured): a long run's progress moves while its metrics are computed too."""
CHUNKS_PER_WORKER = 4
PARALLEL_TICKS = 50_000              # runs of at least this many ticks in all use every core by default


@dataclass(frozen=True)
class Job:
    """One trial: a task file, its settings, and its seed."""

    task_file: str
    settings: SimSettings
    trial: int
    grid: tuple[tuple[str, object], ...] = ()
    keep_series: bool = False
    backend: str = "auto"
    keep_trace: bool = False                  # record every tick (vfdsl.sim.trace)

    @property
    def seed(self) -> int:
        return self.settings.seed + self.trial


@dataclass
class TrialResult:
    trial: int
    seed: int
    grid: tuple[tuple[str, object], ...]
    ticks: int
    fallback_ticks: int                       # ticks solved by the least-violation fallback
    uncertified_ticks: int                    # ticks whose priority levels have no certificate (UNCERTIFIED)
    stats: dict[str, Stats]
    units: dict[str, str]
    series: dict | None = None                # time series of the trial, for plots
    hand: dict | None = None                  # the hand that ran (the generic one when the scene has none)
    trace: dict | None = None                 # column -> one value per tick (vfdsl.sim.trace)
    motion: dict | None = None                # how far the hand's frame moved (achieved_motion)
    procedure: dict | None = None             # a procedure's phases and transitions (PhaseRecord.summary)
    teleop: dict | None = None                # a teleoperated run's figures (TeleopRecord.summary)


@dataclass
class _Loaded:
    task: ir.Task
    controller: vfdsl.Controller
    robot: Robot                              # the simulator's own model of the URDF
    lock: threading.Lock                      # one trial at a time on this controller


_cache: dict[tuple[str, str, int], _Loaded] = {}
_cache_lock = threading.Lock()


def loaded(task_file: str, backend: str = "auto") -> _Loaded:
    """The task, its controller and robot models, and its mesh metrics' queries, built once per process.

    One per thread (a Dask worker may run several threads): each controller owns its solver memory, so the
    threads' trials run in parallel and give what they give alone."""
    key = (str(Path(task_file).resolve()), backend, threading.get_ident())
    with _cache_lock:
        if key not in _cache:
            task = vfdsl.load(task_file)
            if len(task.robots) != 1:
                raise VfError(f"task '{task.name}': the simulator runs tasks with one robot, this one has "
                              f"{len(task.robots)}")
            controller = vfdsl.compile(task, backend=backend)
            prepare_meshes(task)
            _cache[key] = _Loaded(task, controller, Robot.load(task.robots[0].urdf, Path(task.file).parent),
                                  threading.Lock())
        return _cache[key]


def start_configuration(task: ir.Task, settings: SimSettings) -> np.ndarray:
    """Where a trial starts: the recording's start, else the task scene's ``start:``. Neither is an error (the robot
    started at zero clipped into its joint limits, and a fixture then moved it on its own)."""
    if settings.recording is not None and settings.recording.start is not None:
        return settings.recording.start
    if task.start is None:
        where = (f"its scene {task.scene.file} has no `start:`" if task.scene.file else
                 f"it has no scene file ({Path(task.file).with_suffix('.yaml')})")
        raise VfError(f"task '{task.name}': nothing gives the robot's configuration at the start of a run: {where}",
                      hint="give the scene `start: [...]`, one value per joint in the robot's order (in the scene's "
                           "units)")
    return task.start


def run_trial(job: Job, progress=None) -> TrialResult:
    """Simulate one trial and score it."""
    ctx = loaded(job.task_file, job.backend)
    with ctx.lock:
        return simulate_with(job, ctx.task, ctx.controller, ctx.robot, progress)


def simulate_with(job: Job, task: ir.Task, ctrl: vfdsl.Controller, robot: Robot, progress) -> TrialResult:
    """Simulate one trial of ``job`` with a given controller (anything with Controller's interface) and score it.
    The trial starts from the controller's first tick (:meth:`vfdsl.Controller.reset`: a procedure in its initial
    phase, its captures taken again, the teleoperation readout at rest), whatever ran on it before: the controller
    is cached per process, and a trial must not continue the last one's procedure."""
    ctrl.reset()
    s = job.settings
    dt = s.period
    ticks = max(1, int(round(s.duration / dt)))
    hand_rng, tracker_rng, sensor_rng = (np.random.default_rng(x) for x in np.random.SeedSequence(job.seed).spawn(3))
    q0 = start_configuration(task, s)
    scene = Scene(task)
    sim = SimRobot(robot, q0, s.latency, s.servo_lag, robot.resolution if s.resolution == "robot" else None)
    if s.resolution == "robot" and robot.resolution is None:
        raise VfError(f"resolution: robot, but robot '{robot.name}' declares no joint resolution",
                      hint="add resolution to its URDF sidecar (<stem>.yaml), or use resolution: off")
    hand_settings = s.hand or (None if s.pushes or s.operator or (s.recording and s.recording.inputs)
                               else generic_hand(task, ctrl, robot, q0, dt))
    hand = Hand(hand_settings, task, robot, scene, dt, ticks, hand_rng) if hand_settings else None
    scripted = s.pushes or s.presses or s.sensors or s.operator or (s.recording and s.recording.inputs)
    script = ScriptedInputs(s, task, scene, dt, ticks, sensor_rng, robot) if scripted else None
    phases = PhaseRecord(task, ticks) if task.phases else None
    teleop = TeleopRecord(ticks) if teleop_terms(task) else None
    replayed = s.recording.joints if s.recording is not None else None     # the open mode: the recorded joints
    inputs = {i.name: np.zeros(i.size) for i in task.inputs}
    events = sorted(s.disturbances, key=lambda d: d.at)
    segments = [(0, dict(scene.values))]
    params: dict = {}
    moving = Moving(task, scene, s.motions, np.arange(ticks) * dt)
    qs = np.empty((ticks, robot.nq))
    us = np.zeros((ticks, sum(i.size for i in task.inputs)))
    record = _Recorder(task, robot, ctrl, ticks) if job.keep_trace else None
    fallback = uncertified = 0
    solved = ~StepStatus.UNCERTIFIED     # an uncertified answer is still phase 1's (or the same least violation)
    for k in range(ticks):
        t = k * dt
        if events and events[0].at <= t + 1e-12:
            while events and events[0].at <= t + 1e-12:
                d = events.pop(0)
                if d.kind == "move_param":
                    params[d.param] = scene.moved(d.param, d.translate, d.tilt)
                    moving.rebase(d.param, scene.values[d.param], params)
                else:
                    sim.push(task.frame(d.frame), d.by)
            segments.append((k, dict(scene.values)))
        if moving.tables:
            moving.update(k, scene, params)
        q = sim.read() if replayed is None else replayed.at(max(t, replayed.times[0]))
        qs[k] = q
        if script is not None:
            for value in inputs.values():
                value[:] = 0.0
        if hand is not None:
            inputs[hand_settings.input][:] = hand.input(k, q)
        if script is not None:
            script.apply(k, inputs, q)
        if hand is not None or script is not None:
            us[k] = np.concatenate([inputs[i.name] for i in task.inputs])
        try:
            dq = ctrl.step(q, inputs, params or None, dt)
        except VfError as err:
            raise moving.explain(err, t) from None
        if ctrl.status & solved:
            fallback += 1
        uncertified += bool(ctrl.status & StepStatus.UNCERTIFIED)
        if record is not None:
            record.tick(k, inputs, dq, params, scene, ctrl)
        if phases is not None:
            phases.tick(k, ctrl, dt)
        if teleop is not None:
            teleop.tick(k, ctrl)
        if replayed is None:
            sim.command(t, dq)
            sim.advance(t, t + dt)
        if progress is not None and (k + 1) % PROGRESS_EVERY == 0:
            progress(SIMULATED * PROGRESS_EVERY)
    if progress is not None:
        progress(SIMULATED * (ticks % PROGRESS_EVERY))
    result = _score(job, task, robot, qs, segments, tracker_rng, fallback, uncertified, hand_settings,
                    moving.tables, record, progress, phases, teleop)
    if result.motion is not None:
        result.motion["commanded"] = commanded_fraction(ctrl, qs, us, dt)
    return result


def commanded_fraction(ctrl: vfdsl.Controller, qs: np.ndarray, us: np.ndarray, dt: float) -> dict[str, float]:
    """For every tracked part the hand commanded, how much of the commanded motion the robot made over the trial,
    by the encoders: sum_k a_k . f_k / sum_k f_k . f_k, with f_k the rate commanded at tick k and
    a_k = E_k (q_k+1 - q_k) / dt the rate the robot then moved at. Both sums are taken with f and a divided by
    the largest |f| (no overflow); a part never commanded (f = 0 throughout) is left out."""
    names, rows = ctrl.tracked_parts
    n = len(qs) - 1
    if n < 1 or not names:
        return {}
    p = np.tile(ctrl.assembled.context.layout.defaults.reshape(-1, 1), (1, n))
    out = rows.map(n)(qs[:-1].T, us[:-1].T, p, dt)
    dq = np.diff(qs, axis=0)
    fractions = {}
    for k, name in enumerate(names):
        E, f = np.array(out[2 * k]), np.array(out[2 * k + 1])
        E = E.reshape(E.shape[0], n, -1)                           # rows x ticks x joints
        scale = float(np.abs(f).max(initial=0.0))
        if scale > 0:
            achieved = np.einsum("rkj,kj->rk", E, dq) / (dt * scale)
            fractions[name] = float(np.sum(achieved * (f / scale)) / np.sum((f / scale) ** 2))
    return fractions


class _Recorder:
    """A trial's per-tick record (:mod:`vfdsl.sim.trace`): inputs, command, params, status and violations,
    written into arrays allocated once."""

    def __init__(self, task: ir.Task, robot: Robot, ctrl: vfdsl.Controller, ticks: int):
        self.task, self.robot = task, robot
        self.params = tr.runtime_params(task)
        self.input_columns = tr.input_columns(task)
        self.param_columns = [c for d in self.params for c in tr.param_columns(d)]
        self.inputs = np.zeros((ticks, len(self.input_columns)))
        self.dq = np.zeros((ticks, robot.nq))
        self.values = np.zeros((ticks, len(self.param_columns)))
        self.status = np.zeros(ticks, dtype=np.int64)
        self.violations = [""] * ticks

    def tick(self, k: int, inputs: dict, dq: np.ndarray, params: dict, scene: Scene, ctrl) -> None:
        self.inputs[k] = np.concatenate([inputs[i.name] for i in self.task.inputs]) if self.task.inputs else []
        self.dq[k] = dq
        at = 0
        for d in self.params:
            flat = tr.flat_param(params.get(d.name, scene.values[d.name]))
            self.values[k, at:at + len(flat)] = flat
            at += len(flat)
        self.status[k] = int(ctrl.status)
        found = ctrl.violations()
        if found:
            self.violations[k] = "; ".join(map(str, found))

    def columns(self, qs: np.ndarray, period: float) -> dict:
        names, types = self.robot.joint_names, self.robot.joint_types
        out: dict = {"tick": np.arange(len(qs)), "t_s": np.arange(len(qs)) * period}
        for table, cols in ((qs, tr.joint_columns("q", names, types)), (self.dq, tr.joint_columns("dq", names, types)),
                            (self.inputs, self.input_columns), (self.values, self.param_columns)):
            out.update({c: table[:, i] for i, c in enumerate(cols)})
        out["status"] = self.status
        out["violations"] = self.violations
        return out


class Moving:
    """The params a scene's motions move: the displacement of each at every tick (the sum of its motions,
    computed once: ticks x 3, or ticks x 1 for a scalar), and the arrays handed to the controller, allocated
    once and rewritten in place every tick (scene value + displacement; a curve N x 3, every point moved)."""

    def __init__(self, task: ir.Task, scene: Scene, motions, times: np.ndarray):
        self.motions = motions
        self.tables: dict[str, np.ndarray] = {}
        for m in motions:
            self.tables[m.param] = self.tables.get(m.param, 0.0) + m.displacement(times)
        self._base: dict[str, np.ndarray] = {}
        self._out: dict[str, np.ndarray] = {}
        self.arrays: dict[str, np.ndarray] = {}
        for name, table in self.tables.items():
            flat = np.array(flatten(scene.values[name]), dtype=float)
            curve = task.param(name).type == "curve"
            self.arrays[name] = flat.reshape(-1, 3) if curve else flat
            self._out[name] = self.arrays[name] if curve else flat[:table.shape[1]]   # the part that moves
            self._base[name] = self._out[name].copy()

    def rebase(self, name: str, value: ir.Value, params: dict) -> None:
        """A disturbance moved param ``name``: its motions now displace the new value."""
        if name in self.tables:
            flat = np.array(flatten(value), dtype=float)
            self.arrays[name][...] = flat.reshape(self.arrays[name].shape)
            self._base[name][...] = self._out[name]
            params[name] = self.arrays[name]

    def update(self, k: int, scene: Scene, params: dict) -> None:
        """Tick k: every moving param's value in its array, and its displacement in the live scene."""
        for name, table in self.tables.items():
            row = table[k]
            np.add(self._base[name], row, out=self._out[name])
            scene.shifts[name] = row
            params[name] = self.arrays[name]

    def explain(self, err: VfError, t: float) -> VfError:
        """A controller's refusal of a moved value, at the motion that caused it (its scene line)."""
        culprit = next((m for m in self.motions if f"'{m.param}'" in err.message), None)
        if culprit is None:
            return err
        return VfError(f"at t = {t:g} s the scene's {culprit.kind} motion gives param '{culprit.param}' a value the "
                       f"controller refuses: {err.message}", culprit.where,
                       hint="make the motion smaller, or move the param's scene value away from the limit",
                       notes=((f"the refusing check is written at {err.pos}",) if err.pos else ()) + err.notes)


def _score(job: Job, task: ir.Task, robot: Robot, qs: np.ndarray, segments, rng, fallback: int,
           uncertified: int, hand_settings, shifts: dict[str, np.ndarray], record: _Recorder | None = None,
           progress=None, phases: PhaseRecord | None = None, teleop: TeleopRecord | None = None) -> TrialResult:
    s = job.settings
    if phases is not None:              # the phases' fixtures measured against the values they captured
        task, segments = captures.as_params(task), phases.segments(segments)
    poses = frame_poses(robot, task, qs)
    seen = tracker.measure(poses, task, s.noise, s.marker_distance, rng) if s.noise > 0 else None
    defs = metric_defs(task, robot, s.metrics)
    meshes = sum(d.dimension == "clearance" for d in defs) * (1 if seen is None else 2)     # clearances per tick
    if progress is not None and meshes:
        for measured in (poses, seen):
            if measured is not None:
                measured.progress = lambda n: progress((1 - SIMULATED) * n / meshes)
    values: dict[str, list[np.ndarray]] = {}
    units: dict[str, str] = {}
    bounds = [k for k, _ in segments] + [len(qs)]
    for (start, snapshot), end in zip(segments, bounds[1:]):
        part = slice(start, end)
        scene = Scene(task).with_values(snapshot, {name: table[part] for name, table in shifts.items()})
        view = _slice(poses, part)
        seen_view = _slice(seen, part) if seen is not None else None     # one per segment: its clearances kept
        for d in defs:
            values.setdefault(d.name, []).append(errors(d, task, robot, scene, view, qs[part], s.period))
            units[d.name] = d.unit
            if seen_view is not None and d.pose_based:
                name = f"tracker_{d.name}"
                values.setdefault(name, []).append(errors(d, task, robot, scene, seen_view, qs[part], s.period))
                units[name] = d.unit
    owners = {d.name: d.phase for d in defs} | {f"tracker_{d.name}": d.phase for d in defs}
    lengths = [end - start for (start, _), end in zip(segments, bounds[1:])]
    series_values = {name: tr.per_tick(v, lengths) for name, v in values.items()}
    if phases is not None:              # a phase's fixture: NaN where another phase is current
        series_values = {name: phases.mask(owners[name], v) for name, v in series_values.items()}
    trace = None
    if record is not None:
        trace = record.columns(qs, s.period)
        if phases is not None:
            trace.update(phases.columns())
        if teleop is not None:
            trace.update(teleop.columns())
        for name, v in series_values.items():
            tracked = name.startswith("tracker_")
            column = tr.metric_column("tracker" if tracked else "metric", name.removeprefix("tracker_") if tracked
                                      else name, units[name])
            trace[column] = v * tr.metric_factor(units[name])
    stats = {name: Stats().add(v[~np.isnan(v)] if owners[name] else v) for name, v in series_values.items()}
    if progress is not None and not meshes:
        progress((1 - SIMULATED) * len(qs))
    series = None
    if job.keep_series:
        series = {"t": np.arange(len(qs)) * s.period, "metrics": series_values, "p": poses.p, "shifts": shifts,
                  "axis": {f.name: poses.axis(f) for f in task.frames}, "segments": segments,
                  "tracker_p": seen.p if seen is not None else None,
                  "phase": None if phases is None else phases.phase,
                  "phase_names": None if phases is None else phases.names,
                  "teleop": None if teleop is None else teleop.series()}
    hand = None
    if hand_settings is not None:
        hand = {**hand_settings.__dict__,
                "dimension": hand_dimension(task.input(hand_settings.input).type, hand_settings.kind)}
    motion = None
    if hand_settings is not None:
        name = hand_settings.frame or tracked_frame(task, hand_settings.input)
        if name is not None:
            motion = achieved_motion(poses.p[name], poses.axis(task.frame(name)))
            motion["frame"] = name
    procedure = None if phases is None else phases.summary(s.period, series_values, owners)
    return TrialResult(job.trial, job.seed, job.grid, len(qs), fallback, uncertified, stats, units, series, hand, trace,
                       motion, procedure, None if teleop is None else teleop.summary(s.period))


def achieved_motion(p: np.ndarray, axis: np.ndarray) -> dict:
    """How far a frame moved over a trial, by the encoders: the length of its origin's path and the distance
    from its first to its last position (m), and the angle between its first and last tool axis (rad)."""
    return {"path": float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()),
            "net": float(np.linalg.norm(p[-1] - p[0])),
            "turn": float(np.arccos(np.clip(axis[0] @ axis[-1], -1.0, 1.0)))}


def _slice(poses, part: slice):
    return type(poses)({k: v[part] for k, v in poses.p.items()}, {k: v[part] for k, v in poses.R.items()},
                       progress=poses.progress)


def make_jobs(task_file: str, settings: SimSettings, grid: list[tuple[str, list]] | None = None,
              keep_series: bool = False, backend: str = "auto", keep_trace: bool = False) -> list[Job]:
    """Every trial of every grid point (the grid's product, first name slowest), in a fixed order."""
    points: list[tuple[tuple[str, object], ...]] = [()]
    for name, values in grid or []:
        points = [p + ((name, v),) for p in points for v in values]
    jobs = []
    for point in points:
        point_settings = settings.replace(**dict(point))
        for trial in range(settings.trials):
            jobs.append(Job(str(task_file), point_settings, trial, point,
                            keep_series and trial == 0, backend, keep_trace))
    return jobs


def run_trials(jobs: list[Job]) -> list[TrialResult]:
    """Several trials in one worker call (fewer round trips to a pool or a scheduler)."""
    return [run_trial(job) for job in jobs]


def chunks(jobs: list[Job], workers: int) -> list[list[Job]]:
    """The jobs in about four chunks per worker, in order: a worker's start-up and each round trip are paid
    per chunk, and the chunks still balance the load."""
    size = max(1, math.ceil(len(jobs) / (CHUNKS_PER_WORKER * workers)))
    return [jobs[i:i + size] for i in range(0, len(jobs), size)]


def run(jobs: list[Job], workers: int = 1, cluster: str | None = None, progress=None) -> list[TrialResult]:
    """Run the jobs; results in job order whatever order they finish in.

    ``cluster``: the address of a Dask distributed scheduler (or a ``distributed.Client``); else
    ``workers`` local processes (1: this process). ``progress(ticks)`` is called as ticks complete."""
    if cluster is not None:
        return _run_dask(jobs, cluster, progress)
    if workers <= 1 or len(jobs) == 1:
        return [run_trial(job, progress) for job in jobs]
    parts = chunks(jobs, workers)
    results: list[list[TrialResult] | None] = [None] * len(parts)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(run_trials, part): i for i, part in enumerate(parts)}
        for future in as_completed(futures):
            results[futures[future]] = _done(future.result(), progress)
    return [r for part in results for r in part]


def _done(results: list[TrialResult], progress) -> list[TrialResult]:
    if progress is not None:
        progress(sum(r.ticks for r in results))
    return results


def _run_dask(jobs: list[Job], cluster, progress) -> list[TrialResult]:
    from distributed import Client, as_completed as dask_completed

    client = cluster if isinstance(cluster, Client) else connect(str(cluster))     # (an address is probed first)
    try:
        parts = chunks(jobs, max(1, sum(client.nthreads().values())))
        futures = client.map(run_trials, parts, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results: list[list[TrialResult] | None] = [None] * len(parts)
        for future in dask_completed(futures):
            results[index[future.key]] = _done(future.result(), progress)
        return [r for part in results for r in part]
    finally:
        if client is not cluster:
            client.close()


def default_workers(jobs: list[Job]) -> int:
    """Local processes for a run: every core when the run is long enough to pay for starting them (on 2
    cores, 50,000 ticks take 1.7 s in one process and 1.0 s in two, start-up included)."""
    ticks = sum(job.settings.duration / job.settings.period for job in jobs)
    return min(len(jobs), os.cpu_count() or 1) if ticks >= PARALLEL_TICKS else 1
