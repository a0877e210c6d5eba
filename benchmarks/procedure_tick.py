"""A procedure's tick against the same task with one phase, phase by phase, timed in one run (issue 33: "a tick of
the example is within 1.3x of the same task's single-phase tick").

    python benchmarks/procedure_tick.py                 # 30 turns
    python benchmarks/procedure_tick.py --turns 5

The procedure is tasks/procedures/needle_procedure.vf on the native backend, driven through approach, align,
insert, retract and done by a scripted closed loop (record()), recorded once: q, the inputs and dt per tick, and
whether a blend runs in the tick (the 200 ms after each transition: the step then solves its blending case, the one
QP of every phase, vfdsl.compiler.cases; else its phase's steady case). For each phase, its single-phase task is the
same file with that phase's statements outside any phase, no other phase, monitor, transition or blend, and each
capture its statements read a param holding the value the procedure captured (so that its rows are the procedure's
in that phase): the QP of what the procedure does in that phase, and no machine. A turn replays the whole recording
on the procedure (reset first: the same phases at the same ticks, checked) and each phase's recorded states on its
single-phase task, every tick timed around Controller.step (machine, solve and the API's checks), the garbage
collector off. Medians and p99 per phase, steady and blending, in us, and the ratio of the medians; the bound is the
steady ticks'.

One run (2-vCPU EPYC VM, 5 turns): steady approach 1.14x (1.83 against 1.60 us), insert 1.08x (2.41 / 2.24), retract
1.15x (2.23 / 1.94), done 1.15x (1.61 / 1.41): within 1.3x; blending insert 1.87x, retract 2.17x, done 2.54x (align
lasts one tick here: `aligned` holds since the start). Before the cases (one QP at every tick): approach 2.81x.
"""

from __future__ import annotations

import argparse
import gc
import json
import re
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import vfdsl

import tick_timing as timing

EXAMPLE = Path(__file__).resolve().parent.parent / "tasks" / "procedures" / "needle_procedure.vf"
DT = 0.001
BOUND = 1.3


def record(ctrl) -> list[tuple[np.ndarray, dict, float, str, bool]]:
    """The example's scripted closed loop, each phase held past its blend where the example lets it: approach for
    300 ticks, the button, align until aligned (100 ms: all of it within the 200 ms blend), insert for 400 ticks and
    then a 6 N push along the needle until it retracts, a pull out at dt 10 ms until done, done for 400 ticks.
    Per tick: (q, inputs, dt, phase after the tick, whether a blend runs in that tick's step)."""
    q = np.array(ctrl.task.start, dtype=float)
    axis = ctrl.frames(q)["needle"].tool_axis
    out = []

    def tick(hand, go=0.0, dt=DT):
        nonlocal q
        k = len(out) + 1
        wobble = 1e-3 * np.array([np.sin(k), np.cos(1.3 * k), np.sin(0.7 * k)])   # no stale-input watchdog
        inputs = {"hand": np.asarray(hand, float) + wobble, "go": np.array([go])}
        dq = ctrl.step(q, inputs, None, dt)
        activity = ctrl._procedure.activity           # weights, hard flags, funnel widths of this tick's step
        n = len(ctrl.task.phases)
        blending = bool(np.max(activity[:n]) < 1.0 or np.any(activity[2 * n:] != 0))
        out.append((q.copy(), inputs, dt, ctrl.phase, blending))
        q = q + dq

    for k in range(1, 301):
        tick(np.zeros(3), go=1.0 if k == 300 else 0.0)
    while ctrl.phase == "align":
        tick(np.zeros(3))
    for _ in range(400):
        tick(np.zeros(3))
    while ctrl.phase == "insert":
        tick(6.0 * axis)
    while ctrl.phase == "retract" and len(out) < 2000:
        tick(-20.0 * axis, dt=0.01)
    for _ in range(400):
        tick(np.zeros(3))
    return out


def one_phase_text(text: str, phase: str, captures: dict[str, tuple[str, np.ndarray]]) -> str:
    """The procedure's text with ``phase``'s statements outside any phase, no other phase, monitor, transition or
    blend, and each capture those statements read a param of its type and value (``captures``: name -> (type, SI
    value); the file is in mm)."""
    text = re.sub(r"^(monitor|transition|blend) .*\n", "", text, flags=re.M)
    kept = lambda m: re.sub(r"^\s*capture .*\n", "", m.group(2), flags=re.M) if m.group(1) == phase else ""
    text = re.sub(r"^phase (\w+)[^{]*\{\n(.*?)^\}\n", kept, text, flags=re.M | re.S)
    params = ""
    for name, (kind, value) in captures.items():
        if re.search(rf"\b{name}\b", text):
            shown = value * 1000.0 if kind == "point" else value
            params += f"param {name} : {kind} = [{', '.join(repr(float(v)) for v in shown)}]\n"
    text = text.replace("\nparam target : point\n", "\nparam target : point\n" + params)
    return text.replace("task needle_procedure", f"task needle_only_{phase}")


def timed(ctrl, ticks) -> list[int]:
    """ns per tick of Controller.step over ``ticks``."""
    step, pc, out = ctrl.step, time.perf_counter_ns, []
    for q, inputs, dt, *_ in ticks:
        t0 = pc()
        step(q, inputs, None, dt)
        out.append(pc() - t0)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--turns", type=int, default=30)
    args = parser.parse_args()
    task = vfdsl.load(EXAMPLE)
    procedure = vfdsl.compile(task, backend="native")
    recorded = record(procedure)
    phases = list(dict.fromkeys(t[3] for t in recorded))
    kinds = {name: slot.type for name, slot in procedure.assembled.context.layout.capture_slots.items()}
    captures = {}
    procedure.reset()
    singles = {}
    with tempfile.TemporaryDirectory(dir=EXAMPLE.parent.parent, prefix=".one_phase-") as tmp:
        for q, inputs, dt, phase, _ in recorded:           # the captures as the procedure holds them
            procedure.step(q, inputs, None, dt)
            if phase not in captures:
                captures[phase] = {name: (kinds[name], value) for name, value in procedure.captures.items()}
        for phase in phases:
            variant = Path(tmp) / f"{phase}.vf"              # beside the procedure's folder (its imports)
            variant.write_text(one_phase_text(EXAMPLE.read_text(), phase, captures[phase]))
            shutil.copyfile(EXAMPLE.with_suffix(".yaml"), variant.with_suffix(".yaml"))
            singles[phase] = vfdsl.compile(vfdsl.load(variant), backend="native")
    parts = [(phase, blending) for phase in phases for blending in (False, True)
             if any(t[3] == phase and t[4] == blending for t in recorded)]
    timing.log(f"{len(recorded)} ticks recorded: " + ", ".join(
        f"{phase} {'blending' if b else 'steady'} {sum(t[3] == phase and t[4] == b for t in recorded)}"
        for phase, b in parts) + f"; {args.turns} turns")
    procedure_ns = {part: [] for part in parts}
    single_ns = {part: [] for part in parts}
    gc.disable()
    try:
        for _ in range(args.turns):
            procedure.reset()
            for (*_, phase, blending), ns in zip(recorded, timed(procedure, recorded)):
                procedure_ns[phase, blending].append(ns)
            assert procedure.phase == recorded[-1][3]
            for phase, blending in parts:
                single_ns[phase, blending] += timed(singles[phase], [t for t in recorded
                                                                     if t[3] == phase and t[4] == blending])
    finally:
        gc.enable()
    figures = {}
    for phase, blending in parts:
        p = timing.stats(np.array(procedure_ns[phase, blending]))
        s = timing.stats(np.array(single_ns[phase, blending]))
        figures[f"{phase} {'blending' if blending else 'steady'}"] = {
            "procedure": p, "one_phase": s, "ratio_of_medians": p["median_us"] / s["median_us"]}
    steady = [f["ratio_of_medians"] for name, f in figures.items() if name.endswith("steady")]
    print(json.dumps({"machine": timing.machine(), "turns": args.turns, "figures": figures,
                      "worst_steady_ratio_of_medians": max(steady), "bound": BOUND,
                      "steady_within_bound": max(steady) <= BOUND}, indent=2))


if __name__ == "__main__":
    main()
