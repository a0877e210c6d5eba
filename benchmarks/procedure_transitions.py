"""The largest joint acceleration at a procedure's transitions, with the example's blend and without one.

    python benchmarks/procedure_transitions.py          # about 6 s: the example four times, interpreted

The example tasks/procedures/needle_procedure.vf (blend 200 ms), and the same task with every blend 0, are driven
by the same script at dt = 1 ms (tests/test_procedure_runtime.py's, the pull out at 1 ms too): the button at tick
10 (approach -> align), `aligned` at tick 100 (align -> insert), a 6 N push along the needle from tick 150
(insert -> retract 50 ms later), a 20 N pull until the tip is 10 mm out (retract -> done). For each transition at
tick k: the largest joint acceleration |ddq| = max_i |dq_i,j - dq_i,j-1| / dt^2 (dq_j the step of tick j) over
the ticks j in [k - WINDOW_BEFORE, k + blend / dt + WINDOW_AFTER], the entry errors of the entered phase's
funnelled fixtures (beyond their tolerances, in their units) and the ticks solved in least violation in that
window. BOUND is the documented bound on the blended figure (docs/runtime.md, "The funnel, measured");
tests/test_procedure_funnel.py asserts the blended example stays under it and prints the unblended figures.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.ir import model as ir
from vfdsl.runtime.qp import StepStatus

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "tasks" / "procedures" / "needle_procedure.vf"
DT = 0.001
WINDOW_BEFORE, WINDOW_AFTER = 5, 20      # ticks around a transition (and its blend)
LAST_TICK = 2000
PUSH_AFTER, PUSH_TICKS = 50, 60          # the push starts 50 ticks after insert is entered and lasts 60 ticks
ENTRY_OFFSET, PLAN_TILT = 0.8e-3, np.radians(5.0)
FUNNEL_MARGIN = 1.25
BOUND = 1.0
"""rad/s^2: the bound on the blended example's largest joint acceleration at a transition whose fixtures hold at
entry (measured 0.023, a margin of 40x; without the blend, retract -> done is a 10 rad/s^2 stop)."""


def funnel_bound(errors: list[float], blend: float) -> float:
    """The bound on |ddq| at a transition into a fixture entered violated by e (each of ``errors``) with a blend B:
    the funnel's tolerance shrinks at the constant rate e / B from the transition tick, so the fixture's error
    may have to start moving at that rate within one tick, an acceleration e / (B dt) in its unit; FUNNEL_MARGIN
    covers the map to the joints (about 1 on shr7, whose x, y, z and RCM joints move the tip and the needle's
    angle one to one)."""
    return FUNNEL_MARGIN * max(errors) / (blend * DT)


def unblended(task: ir.Task) -> ir.Task:
    """The task with every blend 0: hard rows and weights switch at the transition tick."""
    return task.model_copy(update={"blend": 0.0, "transitions": [t.model_copy(update={"blend": 0.0})
                                                                   for t in task.transitions]})


@dataclass
class Transition:
    """One transition of the run: tick, phases, the largest |ddq| around it (rad/s^2 or m/s^2, per joint), the
    entered phase's entry errors and the least-violation ticks around it."""

    tick: int
    source: str
    target: str
    max_acceleration: float
    entry_errors: list[float]
    least_violation: int


def misplaced_plan(task: ir.Task, q0: np.ndarray, ctrl) -> dict[str, np.ndarray]:
    """Params for the run that enters align violated: the entry ENTRY_OFFSET sideways of the tip (near_entry, < 1 mm,
    still holds; align's stays_at within 0.5 mm is off by 0.3 mm) and the planned line PLAN_TILT off the needle
    (keeps_direction within 1 deg is off by 4 deg)."""
    frames = ctrl.frames(q0)
    axis, tip = frames["needle"].tool_axis, frames["tip"].position
    side = np.cross(axis, [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    entry = tip + ENTRY_OFFSET * side
    depth = np.linalg.norm(np.array(task.param("target").value.xyz) - np.array(task.param("entry").value.xyz))
    planned = np.cos(PLAN_TILT) * axis + np.sin(PLAN_TILT) * side
    return {"entry": entry, "target": entry + depth * planned}


def run(task: ir.Task, misplaced: bool = False) -> list[Transition]:
    """The scripted run of the example at dt = 1 ms (with the misplaced plan: :func:`misplaced_plan`); its
    transitions with their figures. The hand's own steps (its push and its pull starting) are left out of the
    windows: the acceleration they ask is the hand's, with or without a blend."""
    ctrl = vfdsl.compile(task, backend="interpreted")
    q = np.array(task.start, dtype=float)
    axis = ctrl.frames(q)["needle"].tool_axis
    params = misplaced_plan(task, q, ctrl) if misplaced else None
    steps, statuses, events, errors = [], [], [], {}
    inserted = LAST_TICK
    for k in range(1, LAST_TICK + 1):
        if ctrl.phase in ("done", "hold"):
            break
        pushing = inserted + PUSH_AFTER <= k < inserted + PUSH_AFTER + PUSH_TICKS
        pulling = k >= inserted + PUSH_AFTER + PUSH_TICKS
        hand = 6.0 * axis if pushing else (-20.0 * axis if pulling else np.zeros(3))
        wobble = 1e-3 * np.array([np.sin(k), np.cos(1.3 * k), np.sin(0.7 * k)])    # keeps `stale` quiet
        dq = ctrl.step(q, {"hand": hand + wobble, "go": [1.0 if k == 10 else 0.0]}, params, dt=DT)
        q = q + dq
        steps.append(dq)
        statuses.append(int(ctrl.status))
        for event in ctrl.events:
            events.append((k, event))
            errors[k] = [float(e) for e in ctrl._procedure.entry_error if e > 0]
            inserted = k if event.target == "insert" else inserted
    ddq = np.abs(np.diff(np.array(steps), axis=0)).max(axis=1) / DT ** 2    # ddq[j - 2]: ticks j - 1 -> j
    for hand_step in (inserted + PUSH_AFTER, inserted + PUSH_AFTER + PUSH_TICKS):
        ddq[hand_step - 2:hand_step] = 0.0
    lv = np.array([s & StepStatus.LEAST_VIOLATION != 0 for s in statuses])
    found = []
    for k, event in events:
        blend = next(t.blend for t in task.transitions if t.text == event.guard)
        first, last = max(k - WINDOW_BEFORE, 2), min(k + round(blend / DT) + WINDOW_AFTER, len(steps))
        found.append(Transition(k, event.source, event.target, float(ddq[first - 2:last - 1].max()),
                                errors[k], int(lv[first - 1:last].sum())))
    return found


def main() -> None:
    task = vfdsl.load(EXAMPLE)
    runs = [(f"blend {task.blend * 1e3:g} ms", task), ("blend 0", unblended(task))]
    for (name, variant), misplaced in ((r, m) for m in (False, True) for r in runs):
        plan = ", align entered 0.3 mm and 4 deg beyond its tolerances" if misplaced else ""
        print(f"{EXAMPLE.name}, {name}{plan}, dt {DT * 1e3:g} ms:")
        for t in run(variant, misplaced):
            print(f"  tick {t.tick:4d} {t.source:>8} -> {t.target:<8} max |ddq| {t.max_acceleration:10.3f} rad/s^2"
                  f"  least-violation ticks {t.least_violation:3d}  entry errors {[f'{e:.3g}' for e in t.entry_errors]}")
    print(f"documented bounds with the blend: {BOUND:g} rad/s^2 for fixtures met at entry; "
          f"{FUNNEL_MARGIN:g} e / (B dt) for one entered violated by e")


if __name__ == "__main__":
    main()
