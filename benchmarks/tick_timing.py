"""How benchmarks/tick.py (and benchmarks/export_tick.py) time a tick: the machine they run on, a timer per
variant (the step Function called bare, or the whole Controller.step API), the variants' ticks taken in turns
with the garbage collector disabled, their statistics, and the closed-loop states they are timed on."""

from __future__ import annotations

import contextlib
import gc
import importlib.metadata
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np

import vfdsl
from vfdsl import pipeline
from vfdsl.codegen.build import build_library
from vfdsl.compiler.admissible import Admissible
from vfdsl.compiler.assemble import assemble
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.native import BufferedFunction
from vfdsl.runtime.qp import build_step_function

WARMUP = 1_000
BLOCK = 250     # ticks a variant runs before the next one's turn (interleaved): 80 turns each in a full run, so that
                # a second of load on the shared machine falls on a few turns of every variant, not on the median of
                # one; the first tick of a turn runs with cold caches (0.4 % of the ticks)


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# ------------------------------------------------------------------------------------------ machine
def machine() -> dict:
    cpu = "unknown"
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    try:
        cc = subprocess.run([os.environ.get("CC", "cc"), "--version"], check=False, capture_output=True, text=True)
        cc_line = cc.stdout.splitlines()[0] if cc.stdout else "unavailable"
    except OSError:
        cc_line = "unavailable"

    def version(dist: str) -> str:
        try:
            return importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            return "not installed"

    import casadi
    info = {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "cores_usable": len(os.sched_getaffinity(0)),
        "kernel": platform.release(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "casadi": casadi.__version__,
        "pinocchio": version("pin"),
        "pink": version("pin-pink"),
        "daqp": version("daqp"),
        "qpsolvers": version("qpsolvers"),
        "vfdsl": vfdsl.__version__,
        "cc": cc_line,
        "loadavg": os.getloadavg()[0],
    }
    pc = time.perf_counter_ns
    samples = np.empty(20_000, np.int64)
    for k in range(samples.size):
        t0 = pc()
        samples[k] = pc() - t0
    info["timer_overhead_ns"] = float(np.median(samples))
    return info


# ------------------------------------------------------------------------------------------- timing
def stats(ns: np.ndarray) -> dict:
    us = ns / 1e3
    return {"median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()), "ticks": int(us.size)}


def raw_generated(task, library) -> BufferedFunction:
    """The library's generated step, called bare: inputs already in its buffers, no argument handling."""
    return BufferedFunction.native(library.so_path, pipeline.symbol_prefix(task))


def one_level(task, cache: Path) -> BufferedFunction:
    """The task's generated step with its priority levels summed into one cost (qp_data's first 7 outputs: what
    the least-violation phase minimizes), built and called bare as :func:`raw_generated`."""
    robot = Robot.load(task.robots[0].urdf)
    problem = assemble(task, robot)
    f = problem.function
    args = f.sx_in() if f.is_a("SXFunction") else f.mx_in()     # (of the same kind as the task's own qp_data)
    summed = ca.Function("qp_data", args, f.call(args)[:7], f.name_in(), f.name_out()[:7])
    prefix = pipeline.symbol_prefix(task) + "_one"
    step = build_step_function(summed, prefix, row_groups=problem.row_groups,
                               feas_tol=pipeline.FEASIBILITY_TOLERANCE, native=True)
    library = build_library(step, prefix, cache, {"one_level": True}, Admissible(task, robot.reach).function)
    return BufferedFunction.native(library.so_path, prefix)


def interleaved(timers: dict, ticks: int, block: int = BLOCK) -> dict:
    """Every timer's ticks 0..ticks-1, taken in turns of ``block`` ticks (after WARMUP ticks each, k < 0), with the
    garbage collector disabled: ``timer(k)`` runs and times tick k. In turns, a burst of load on the shared machine
    falls on every variant alike instead of on the few milliseconds one variant's ticks would take in a row (B's
    20,000 ticks: 60 ms), and the ratios of one run compare ticks of the same moments. Returns name -> the ticks'
    figures (what the timer returns) as an array."""
    samples: dict = {name: [] for name in timers}
    gc.disable()
    try:
        for timer in timers.values():
            for k in range(-WARMUP, 0):
                timer(k)
        for first in range(0, ticks, block):
            for name, timer in timers.items():
                samples[name].extend(timer(k) for k in range(first, min(first + block, ticks)))
    finally:
        gc.enable()
    return {name: np.array(values) for name, values in samples.items()}


def raw_ticks(step, qs, us, p, dt: float, statuses: dict) -> Callable[[int], int]:
    """tick(k) -> ns of one evaluate() at recorded state k, its inputs written into the bound arrays first (outside
    the timed region); the status of every timed tick (k >= 0) counted in ``statuses``."""
    q_buf, u_buf, p_buf, dt_buf, _ = step.inputs
    p_buf[:] = p
    dt_buf[...] = dt
    evaluate, pc, m = step.evaluate, time.perf_counter_ns, len(qs)
    status_buf = step.outputs[1]

    def tick(k: int) -> int:
        i = k % m
        q_buf[:] = qs[i]
        u_buf[:] = us[i]
        t0 = pc()
        evaluate()
        t1 = pc()
        if k >= 0:
            s = int(status_buf[0])
            statuses[s] = statuses.get(s, 0) + 1
        return t1 - t0
    return tick


def step_ticks(ctrl, qs, inputs: list[dict], dt: float, params: dict | None = None,
               move=lambda i: None) -> Callable[[int], int]:
    """tick(k) -> ns of the whole Controller.step API at recorded state k, its q and inputs first copied into arrays
    and a mapping made beforehand (outside the timed region), as a control loop updates its own from the sensors
    (and as :func:`raw_ticks` writes the bound arrays: no variant reads its inputs cold from the recording);
    ``params`` (preallocated arrays, or lists) are changed by move(i) before the tick at recorded state i, as they
    were when the states were recorded."""
    step, pc, m = ctrl.step, time.perf_counter_ns, len(qs)
    q = np.empty(qs.shape[1])
    u = {name: np.empty_like(value) for name, value in inputs[0].items()}

    def tick(k: int) -> int:
        i = k % m
        q[:] = qs[i]
        for name, value in inputs[i].items():
            u[name][...] = value
        move(i)
        t0 = pc()
        step(q, u, params, dt)
        return pc() - t0
    return tick


def time_raw(step, qs, us, p, dt: float, ticks: int) -> tuple[dict, dict]:
    """Statistics of :func:`raw_ticks` alone, and the statuses of its ticks."""
    statuses: dict[int, int] = {}
    return stats(interleaved({"raw": raw_ticks(step, qs, us, p, dt, statuses)}, ticks)["raw"]), statuses


def time_step(ctrl, qs, inputs: list[dict], dt: float, ticks: int, params: dict | None = None,
              move=lambda i: None) -> dict:
    """Statistics of :func:`step_ticks` alone."""
    return stats(interleaved({"step": step_ticks(ctrl, qs, inputs, dt, params, move)}, ticks)["step"])


def record(ctrl, q0, inputs_of, dt: float, count: int,
           params: dict | None = None) -> tuple[np.ndarray, np.ndarray, list[dict], dict]:
    """A closed-loop trajectory (q <- q + dq) driven by inputs_of(k, q) -> {name: array}."""
    q = np.array(q0, dtype=float)
    qs, us, dicts, statuses = [], [], [], {}
    for k in range(count):
        inputs = inputs_of(k, q)
        qs.append(q.copy())
        dicts.append({name: np.asarray(v, dtype=float) for name, v in inputs.items()})
        us.append(np.concatenate([np.ravel(inputs[name]) for name in ctrl.input_sizes] or [np.zeros(0)]))
        q = q + ctrl.step(q, inputs, params, dt)
        statuses[int(ctrl.status)] = statuses.get(int(ctrl.status), 0) + 1
    return np.array(qs), np.array(us), dicts, statuses
