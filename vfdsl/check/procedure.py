"""``vfdsl check`` of a procedure (phases, monitors, transitions): what the IR alone decides.

- the phase machine's graph (:mod:`.statechart`) and the monitors' ranges (:mod:`.monitors`);
- **entering a phase** (VF956, VF957): a hard fixture whose error is a monitor measure (``stays_at``,
  ``within_distance``, ``within_sphere``: the distance from the frame's origin to their point; ``along``: to its
  line; ``keeps_direction``: the angle of the tool axis to its direction) may be violated at the tick a
  transition enters its phase. Its error there is bounded by the guard (the hull of the values the measure takes
  where the guard holds, :func:`.monitors.bounds`) and by the source phase's hard fixtures on the same measure
  (their stated size); it is 0 when the fixture's geometry is captured on entry from the same frame (a point of
  its origin, a line through it, its tool axis). Past the fixture's size, the entry is violated by up to the
  excess: with a blend the funnel brings it in over the blend (a note), unless the excess is more than the
  fixture's one-tick reach at the rate limits (VF204, in the phase entered) times the blend's ticks: then the tool
  lags its funnel at the speed limits (a warning); without a blend the rows snap it in one tick (a warning). A
  guard that keeps the measure beyond the size violates every entry (a warning);
- **fixtures of every phase** (VF958, VF959): the statements outside the phases hold in every phase (one note lists
  them); a phase that states the same primitive on the same frame and geometry with a looser tolerance cannot
  loosen it (an error).

The analyses that need a compiled controller (feasibility, residuals, hands off, kinematics, meshes, the random
walk, redundancy) run on each phase alone (:func:`phase_tasks`: the statements outside the phases and the phase's
own, its captures read as params holding their values at the start configuration, as if the phase were entered
there), each finding saying in which phases it holds (:func:`per_phase`). A phase that reads a captured input or
scalar is not analysed so: one note (VF950) says so.
"""

from __future__ import annotations

import math
from dataclasses import replace

from vfdsl.check import hygiene, monitors, statechart
from vfdsl.ir.constraints import describe, where
from vfdsl.check.monitors import arg_key, arrow, axis, measure_key, origin
from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.compiler import derived
from vfdsl.ir import captures
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS
from vfdsl.runtime.values import ASSUMED_PERIOD

COMPILED = ("feasibility at the start", "residuals", "kinematics", "ports' levers", "meshes", "hands off",
            "the random walk", "redundancy and contradiction")


def is_procedure(task: ir.Task) -> bool:
    return bool(task.phases or task.monitors or task.transitions)


def every_statement(task: ir.Task) -> ir.Task:
    """The task with every phase's statements beside the phase-less ones: for the analyses of one statement at a
    time (polytopes, tolerances, speeds, unused declarations)."""
    return task.model_copy(update={"constraints": task.every_constraint, "objectives": task.every_objective})


def analyse(task: ir.Task) -> list[Finding]:
    """What the IR decides, but the entries (:func:`entries`: they are measured against the phases' analyses)."""
    return [*statechart.analyse(task), *monitors.analyse(task), *_every_phase(task), *_captured_directions(task)]


def phase_tasks(task: ir.Task, backend: str) -> dict[str, ir.Task | None]:
    """Each phase alone (:func:`vfdsl.ir.captures.phase_task`), its captures at their values after the first tick
    from the start configuration with every input 0 (each capture's start value); None for a phase that cannot be
    analysed alone."""
    import numpy as np

    from vfdsl.pipeline import compile as compile_task

    ctrl = compile_task(task, backend="interpreted" if backend == "auto" else backend)
    ctrl.step(task.start, {name: np.zeros(n) for name, n in ctrl.input_sizes.items()})
    given = captures.values(task, ctrl.captures)
    return {phase.name: captures.phase_task(task, phase.name, given) for phase in task.phases}


def not_compiled(task: ir.Task, phase: str) -> Finding:
    return Finding("procedure-not-compiled", Severity.NOTE,
                   f"phase '{phase}' reads a captured input or scalar: the analyses of its compiled controller ("
                   + ", ".join(COMPILED) + ") are not run on it; its statements, monitors and transitions were "
                   "checked", next(p.span for p in task.phases if p.name == phase), None, "task",
                   {"skipped": list(COMPILED), "phase": phase})


def per_phase(found: dict[str, list[Finding]], known: list[Finding]) -> list[Finding]:
    """The findings of the phases' analyses, one per distinct finding, each saying where it holds ("in phase
    insert", "in phases a, b", "in every phase"; ``data["phases"]``); those already in ``known`` (of the task's
    statements) left out."""
    def key(f: Finding):
        return f.name, f.severity, f.span, f.message, f.subject

    seen = {key(f) for f in known}
    where: dict = {}
    first: dict = {}
    for phase, findings in found.items():
        for f in findings:
            if key(f) not in seen:
                where.setdefault(key(f), []).append(phase)
                first.setdefault(key(f), f)
    out = []
    for k, phases in where.items():
        f = first[k]
        label = ("in every phase" if len(phases) == len(found) and len(found) > 1
                 else f"in phase{'s' if len(phases) > 1 else ''} {', '.join(phases)}")
        message = f.message if f.name == "procedure-not-compiled" else f"{label}: {f.message}"
        out.append(replace(f, message=message, data={**f.data, "phases": phases}))
    return out


def unused(task: ir.Task) -> list[Finding]:
    """VF801 over every phase's statements, monitors and captures."""
    used = set()
    for m in [*task.monitors, *task.transitions]:
        for c in _measures(m.expr if isinstance(m, ir.Monitor) else m.guard):
            used |= _uses(c)
    for c in (c for p in task.phases for c in p.captures):
        used |= _uses(c.source)
    return [f for f in hygiene.unused(every_statement(task)) if (f.data["kind"], f.data["name"]) not in used]


def _measures(expr: ir.MonitorExpr):
    if isinstance(expr, (ir.Compare, ir.Flag)):
        yield expr.measure
    for item in getattr(expr, "items", []):
        yield from _measures(item)


def _uses(value) -> set[tuple[str, str]]:
    """(kind, name) of the frames, inputs and params a measure or capture source reads."""
    out = set()
    if getattr(value, "frame", None):
        out.add(("frame", value.frame))
    if getattr(value, "input", None):
        out.add(("input", value.input))
    if isinstance(value, ir.InputRef):
        out.add(("input", value.name))
    if isinstance(value, ir.ParamRef):
        out.add(("param", value.name))
    for arg in (getattr(value, "to", None), getattr(value, "direction", None)):
        for leaf in (derived.leaves(arg) if arg is not None else ()):
            out |= _uses(leaf)
            if isinstance(leaf, ir.FrameRef):
                out.add(("frame", leaf.name))
    return out


# --------------------------------------------------------------------------------------------- entering a phase
def fixture_measure(c: ir.Constraint) -> tuple[ir.Measure, float] | None:
    """(the monitor measure a hard constraint bounds, its stated size), or None for a constraint that bounds none."""
    spec = CONSTRAINTS.get(c.primitive)
    if spec is None or c.soft or c.frame is None:
        return None
    if spec.error_is_distance and spec.reference_point:
        size = c.tolerance
        if spec.stated_by is not None:
            stated = c.args.get(spec.stated_by[1])
            size = stated.value.value if isinstance(stated, ir.Const) else None
        return (ir.Distance(frame=c.frame, to=c.args[spec.reference_point]), size) if size is not None else None
    kinds = {a.kind: a.name for a in spec.args}
    if spec.tolerance == "length" and list(kinds) == ["line"]:
        return ir.Distance(frame=c.frame, to=c.args["line"]), c.tolerance
    if spec.true_angle is not None and spec.kept_angle == 0.0 and "direction" in kinds:
        return ir.Angle(frame=c.frame, direction=c.args[kinds["direction"]]), c.tolerance
    return None


def _captured_on_entry(task: ir.Task, phase: ir.Phase, m: ir.Measure) -> bool:
    """The measure is 0 at the phase's entry: its geometry is captured then from the frame itself."""
    captured = {c.name: c.source for c in phase.captures if isinstance(c.source, ir.FrameMeasure)}

    def taken(arg, part: str, same) -> bool:
        source = captured.get(arg.name) if isinstance(arg, ir.CaptureRef) else None
        return source is not None and source.part == part and same(task, source.frame) == same(task, m.frame)

    if isinstance(m, ir.Angle):
        return taken(m.direction, "axis", axis)
    to = m.to
    points = to.operands[:1] if isinstance(to, ir.Derived) and to.op == "line" else \
        to.operands if isinstance(to, ir.Derived) and to.op == "line2" else [to]
    return any(taken(arg, "position", origin) for arg in points)


def entries(task: ir.Task, figures: dict) -> list[Finding]:
    """VF956 and VF957 for every transition and fixture of the phase it enters. ``figures``: the phases' figures
    (``figures.phases``), whose ``reach_per_tick`` (VF204's one-tick reach at the rate limits, by the constraint's
    line) tells whether a blend's funnel can be followed; without them (no start) the funnel is taken to be."""
    phases = {p.name: p for p in task.phases}
    period = task.scene.period or ASSUMED_PERIOD
    findings = []
    for t in task.transitions:
        target = phases[t.target]
        for c in target.constraints:
            fixture = fixture_measure(c)
            if fixture is None or _captured_on_entry(task, target, fixture[0]):
                continue
            measure, size = fixture
            guard = monitors.bounds(task, t.guard, measure)
            if guard.empty:
                continue                                    # never fires: VF954
            entries = [(min(guard.hi, _held(task, phases[s], measure)), s) for s in statechart.sources(task, t)]
            if not entries:
                continue                                    # a `*` that leaves no phase
            worst, source = max(entries)
            reach = figures.get(t.target, {}).get("reach_per_tick", {}).get(where(c))
            findings += _entry(task, t, c, measure, size, guard.lo, worst, source, reach, period)
    return findings


def _held(task: ir.Task, phase: ir.Phase, m: ir.Measure) -> float:
    """The smallest stated size of the source phase's (and the task's) hard fixtures on the measure."""
    key = measure_key(task, m)
    sizes = [f[1] for c in [*task.constraints, *phase.constraints] if (f := fixture_measure(c)) is not None
             and measure_key(task, f[0]) == key]
    return min(sizes, default=math.inf)


def _entry(task, t: ir.Transition, c: ir.Constraint, m: ir.Measure, size: float, least: float, worst: float,
           source: str, reach: float | None, period: float) -> list[Finding]:
    kind = "angle" if isinstance(m, ir.Angle) else "length"
    fixture = f"{describe(c)} within {quantity(size, kind)} at {where(c)}"
    subject = f"transition {arrow(t)}"
    data = {"constraint": describe(c), "where": where(c), "size": size, "least": least, "worst": worst,
            "blend": t.blend, "source": source}
    measured = monitors.describe(m)
    if least > size:
        how = (f"the funnel drags the tool {quantity(least - size, kind)} or more within {quantity(t.blend, 'time')}"
               if t.blend else f"the rows pull the tool {quantity(least - size, kind)} or more at once")
        return [Finding("entry-always-violated", Severity.WARNING,
                        f"{arrow(t)} fires only where {measured} is at least {quantity(least, kind)}, so it always enters "
                        f"'{t.target}' with {fixture} violated by at least {quantity(least - size, kind)}: {how}",
                        t.span, "is the fixture's geometry the one meant (a capture of this phase, taken on "
                        "entry?)", subject, data)]
    if worst <= size:
        return []
    excess = "any amount" if math.isinf(worst) else f"up to {quantity(worst - size, kind)}"
    unbounded = not worst < monitors.measure_range(task, m).hi
    bound = f"neither its guard nor '{source}' bounds {measured}" if unbounded else \
        f"its guard lets {measured} reach {quantity(worst, kind)}"
    if t.blend:
        # the funnel shrinks the excess e to 0 over the blend: e dt / B per tick, which the rate limits allow only
        # up to the fixture's one-tick reach r (VF204); beyond e = r B / dt the tool lags its funnel at the speed
        # limits, every tick a least-violation one, until it is within the fixture
        funnelled = math.inf if reach is None or not reach > 0 else reach * max(1, math.ceil(t.blend / period - 1e-9))
        if unbounded or worst - size <= funnelled:         # unbounded: the kinematics may bound it, not stated
            within = "" if math.isinf(funnelled) or worst - size <= funnelled else \
                f" from up to {quantity(funnelled, kind)} beyond it (at the speed limits)"
            return [Finding("entry-unfunnelled", Severity.NOTE,
                            f"{arrow(t)}: {bound}, so it can enter '{t.target}' with {fixture} violated by {excess}; "
                            f"its blend's funnel brings it within {quantity(size, kind)} in "
                            f"{quantity(t.blend, 'time')}{within}", t.span, None, subject, data)]
        ticks = math.ceil((worst - size) / reach)
        return [Finding("entry-unfunnelled", Severity.WARNING,
                        f"{arrow(t)}: {bound}, so it can enter '{t.target}' with {fixture} violated by {excess}; its "
                        f"blend's funnel ({quantity(t.blend, 'time')}) cannot bring it in: at the speed limits one "
                        f"tick ({quantity(period, 'time')}) moves only {quantity(reach, kind)} along its worst facet, "
                        f"{quantity(funnelled, kind)} over the blend, so the tool lags the funnel at its speed limits "
                        f"(least violation) for about {ticks} ticks ({ticks * period:.3g} s)", t.span,
                        f"a blend of more than {quantity(ticks * period, 'time')} (the reach is the start's: leave a "
                        f"margin), a guard within "
                        f"{quantity(size + funnelled, kind)}, or higher speed limits", subject,
                        {**data, "reach_per_tick": reach, "ticks": ticks})]
    return [Finding("entry-unfunnelled", Severity.WARNING,
                    f"{arrow(t)}: {bound}, so it can enter '{t.target}' with {fixture} violated by {excess}, and "
                    f"with no blend its rows snap it in one tick", t.span,
                    "add a blend so the funnel reaches it (`blend 200 ms` after the transition or task-wide), or a "
                    "guard within the fixture's size", subject, data)]


# ------------------------------------------------------------------------------------------ captured directions
def _captured_directions(task: ir.Task) -> list[Finding]:
    """VF960: a phase's fixture whose direction (a normalized vector, a line through two points, a line's direction
    or a plane's normal) is derived from two or more captured points: where they coincide it has none, and the
    controller holds the tool still with its rows undefined (docs/runtime.md, "A fixture's geometry from
    captures")."""
    points = {c.name for p in task.phases for c in p.captures if c.kind == "point"}
    findings = []
    for phase in task.phases:
        for c in phase.constraints:
            for node in (n for arg in c.args.values() for n in _normalizing(arg)):
                names = sorted({leaf.name for operand in _normalized_operands(node)
                                for leaf in derived.leaves(operand)
                                if isinstance(leaf, ir.CaptureRef) and leaf.name in points})
                if len(names) >= 2:
                    findings.append(Finding(
                        "captured-direction", Severity.NOTE,
                        f"{describe(c)} at {where(c)} takes its direction from the captured points "
                        f"{', '.join(names)}: where they coincide (the frame not moved between the captures) it has "
                        "none, and the controller then holds the tool still (FALLBACK, its rows named undefined)",
                        node.span, "capture the points where the frame has moved between them, or state the "
                        "direction otherwise (a param, a captured axis)", f"{describe(c)} at {where(c)}",
                        {"constraint": describe(c), "where": where(c), "captures": names}))
    return findings


def _normalizing(arg):
    """The derived nodes in ``arg`` that normalize a vector."""
    if isinstance(arg, ir.Derived):
        if arg.op in ("normalize", "line2", "line", "plane"):
            yield arg
        for operand in arg.operands:
            yield from _normalizing(operand)


def _normalized_operands(node: ir.Derived):
    """The operands whose difference or value a normalizing node divides by its length."""
    return node.operands if node.op in ("normalize", "line2") else node.operands[1:]


# ------------------------------------------------------------------------------------------ fixtures of every phase
def _every_phase(task: ir.Task) -> list[Finding]:
    if not task.phases:
        return []
    findings = []
    if task.constraints:
        listed = "; ".join(f"{describe(c)} at {where(c)}" for c in task.constraints)
        findings.append(Finding("every-phase-fixtures", Severity.NOTE,
                                f"{len(task.constraints)} constraint{'s' * (len(task.constraints) != 1)} outside the "
                                f"phases hold in every phase ({', '.join(p.name for p in task.phases)}): {listed}",
                                task.constraints[0].span, None, "every phase",
                                {"constraints": [where(c) for c in task.constraints]}))
    for phase in task.phases:
        for c in phase.constraints:
            for wide in task.constraints:
                if _same_fixture(c, wide) and c.tolerance > wide.tolerance:
                    findings.append(Finding(
                        "fixture-loosened", Severity.ERROR,
                        f"phase '{phase.name}' states {describe(c)} within {_size(c)}, looser than the same "
                        f"fixture at {where(wide)} (within {_size(wide)}), which holds in every phase: the looser "
                        f"one loosens nothing", c.span,
                        "state the looser tolerance outside the phases and the tighter ones in the phases that need "
                        "them", f"{describe(c)} at {where(c)}",
                        {"phase": phase.name, "tolerance": c.tolerance, "every_phase": wide.tolerance,
                         "other": where(wide)}))
    return findings


def _same_fixture(c: ir.Constraint, wide: ir.Constraint) -> bool:
    return (not wide.soft and c.primitive == wide.primitive and c.frame == wide.frame
            and c.tolerance is not None and wide.tolerance is not None
            and {k: arg_key(v) for k, v in c.args.items()} == {k: arg_key(v) for k, v in wide.args.items()})


def _size(c: ir.Constraint) -> str:
    return quantity(c.tolerance, CONSTRAINTS[c.primitive].tolerance or "")
