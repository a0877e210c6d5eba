"""A procedure's phase machine as a graph: phases no run reaches (VF951), phases with no way out (VF952), and
transitions whose guards can hold together (VF953).

A transition leaves its source phase, or with ``*`` every phase but a final one and its target; one whose guard
can never hold (:mod:`.monitors`) is no edge. Reachable: the initial phase and every target of an edge out of a
reachable phase. Two transitions overlap when they leave a phase in common and their guards can hold together
(decided from the comparisons, :mod:`.monitors`): the first in file order fires; when the later one's guard
implies the earlier's, it never fires from the phases they share (a warning).
"""

from __future__ import annotations

from vfdsl.check.monitors import arrow, can_hold, hold_together
from vfdsl.check.report import Finding, Severity
from vfdsl.ir import model as ir


def sources(task: ir.Task, t: ir.Transition) -> list[str]:
    """The phases ``t`` can leave."""
    if t.source is not None:
        return [t.source]
    return [p.name for p in task.phases if not p.final and p.name != t.target]


def analyse(task: ir.Task) -> list[Finding]:
    """VF951-VF953 (none for monitors without phases)."""
    if not task.phases:
        return []
    firing = [t for t in task.transitions if can_hold(task, t.guard)]
    dead = [t for t in task.transitions if t not in firing]
    return [*_reachability(task, firing, dead), *_overlaps(task, firing)]


def reachable(task: ir.Task, firing: list[ir.Transition]) -> set[str]:
    initial = next(p.name for p in task.phases if p.initial)
    seen, todo = {initial}, [initial]
    while todo:
        phase = todo.pop()
        for t in firing:
            if phase in sources(task, t) and t.target not in seen:
                seen.add(t.target)
                todo.append(t.target)
    return seen


def _reachability(task: ir.Task, firing, dead) -> list[Finding]:
    findings = []
    seen = reachable(task, firing)
    initial = next(p.name for p in task.phases if p.initial)
    for phase in task.phases:
        subject = f"phase {phase.name}"
        into = [t for t in firing if t.target == phase.name]
        never = [t for t in dead if t.target == phase.name]
        if phase.name not in seen:
            if into:
                why = "transitions lead to it only from phases that are never reached: " + \
                      ", ".join(sorted({s for t in into for s in sources(task, t)}))
            elif never:
                why = "the transitions into it can never fire: " + ", ".join(arrow(t) for t in never)
            else:
                why = "no transition leads to it"
            findings.append(Finding("phase-unreachable", Severity.ERROR,
                                    f"phase '{phase.name}' is never entered from the initial phase '{initial}': {why}",
                                    phase.span, f"add a transition into '{phase.name}', or remove the phase", subject,
                                    {"phase": phase.name, "initial": initial}))
            continue
        if phase.final:
            continue
        out = [t for t in firing if phase.name in sources(task, t)]
        if not out:
            blocked = [t for t in dead if phase.name in sources(task, t)]
            why = ("its transitions can never fire: " + ", ".join(arrow(t) for t in blocked)) if blocked else \
                "no transition leaves it"
            findings.append(Finding("phase-dead-end", Severity.WARNING,
                                    f"phase '{phase.name}' is not final and has no way out: {why}", phase.span,
                                    f"mark it `final`, or add a transition out of '{phase.name}'", subject,
                                    {"phase": phase.name}))
    return findings


def _overlaps(task: ir.Task, firing) -> list[Finding]:
    findings = []
    for k, later in enumerate(firing):
        for first in firing[:k]:
            shared = [s for s in sources(task, later) if s in sources(task, first)]
            if not shared or not hold_together(task, first.guard, later.guard):
                continue
            where = "'" + "', '".join(shared) + "'"
            data = {"first": first.span.line, "later": later.span.line, "phases": shared}
            if not can_hold(task, ir.And(items=[later.guard, ir.Not(items=[first.guard])])):
                findings.append(Finding(
                    "guards-overlap", Severity.WARNING,
                    f"transition {arrow(later)} never fires from {where}: whenever `{later.text}` holds, "
                    f"`{first.text}` of {arrow(first)} holds too, and the first in file order wins",
                    later.span, "reorder the transitions, or make the guards exclusive", f"transition {arrow(later)}",
                    data))
                continue
            findings.append(Finding(
                "guards-overlap", Severity.NOTE,
                f"from {where}, the guards of {arrow(first)} (`{first.text}`) and {arrow(later)} (`{later.text}`) "
                f"can hold together: the first in file order, line {first.span.line}, wins", later.span,
                None, f"transition {arrow(later)}", data))
    return findings
