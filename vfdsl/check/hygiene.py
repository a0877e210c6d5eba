"""Hygiene: declarations nothing uses, constraints that add nothing, and pairs that can never both hold.

- **Unused declarations** (VF801): a frame, input or param that no constraint, objective, used param
  (through ``in``) or other frame (as its base, ``frame b = a ...``) refers to.
- **Redundant constraints** (VF802): constraint c is implied by the other hard geometric constraints and
  the joint limits when every bounded row a_i dq >= lb_i of c holds at the minimum of a_i dq over the
  others' rows (an LP per row, HiGHS), at the start and at every 10th state of check's random walk (the
  region the task reaches; at most REDUNDANCY_STATES of them, evenly spaced) where c has a bounded row; never
  when a row of c is degenerate (zero gradient) at one of them. Rate limits (joint and frame speeds) are left
  out: within one tick they make almost every bound look redundant. Later statements are tested first, so of
  two duplicates the second is reported.
- **Inactive constraints** (VF804, a note): every row of c is unbounded (``0 >= -inf``: a mesh beyond reach)
  at all of these states. Such rows hold whatever the motion, which shows nothing about the states where c
  acts: inactive is not redundant.
- **Contradictory tolerances** (VF803): two hard geometric constraints whose rows alone, without any
  joint limit or speed, have no common motion (their margin LP is negative): e.g. two points to stay at,
  farther apart than the sum of their tolerances.
- **Weights beyond resolution** (VF805): the terms of one priority level (objectives, soft constraints' slacks),
  in one phase with the phase-less ones, whose weights span more than WEIGHT_SPAN: the level's cost sums them, and
  the solver, whose tolerances are ~1e-10 of the level's scale, no longer resolves the lighter one (weights 1e-9 and
  1e9 in one level: the lighter soft target pulled the tool as if its weight were the heavier's).
"""

from __future__ import annotations

import itertools

import numpy as np

from vfdsl.check.linearized import ConstraintRows
from vfdsl.ir.constraints import describe, subject, where
from vfdsl.check.lp import FEASIBLE, LinearSystem
from vfdsl.check.report import Finding, Severity
from vfdsl.compiler import derived
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS

DEGENERATE = 1e-9               # a row whose gradient is this small (relative) measures nothing about dq
REDUNDANCY_STATES = 20          # reached states (besides the start) at which a redundancy is confirmed
IMPLIED = 1e-10                  # a row is implied when the others keep it satisfied to this much (m or rad)
WEIGHT_SPAN = 1e10               # the largest ratio of two weights in one priority level the solver resolves


def weight_span(task: ir.Task) -> list[Finding]:
    """VF805 for each priority level (each phase's with the phase-less terms) whose weights span more than
    WEIGHT_SPAN: naming the lightest and the heaviest term."""
    views = [(None, task.constraints, task.objectives)]
    views += [(p.name, [*task.constraints, *p.constraints], [*task.objectives, *p.objectives]) for p in task.phases]
    findings, seen = [], set()
    for phase, constraints, objectives in views:
        levels: dict[int, list] = {}
        for o in objectives:
            levels.setdefault(o.priority, []).append((o.weight, f"minimize {o.term}", o.span))
        for c in constraints:
            if c.soft:
                levels.setdefault(c.priority, []).append((c.weight, describe(c), c.span))
        for level, terms in sorted(levels.items()):
            light = min(terms, key=lambda term: term[0])
            heavy = max(terms, key=lambda term: term[0])
            key = (level, light[2], heavy[2])
            if heavy[0] <= WEIGHT_SPAN * light[0] or key in seen:
                continue
            seen.add(key)
            in_phase = f" (phase {phase})" if phase else ""
            findings.append(Finding(
                "weights-span", Severity.WARNING,
                f"priority level {level}{in_phase} weighs {light[1]} by {light[0]:g} and {heavy[1]} by "
                f"{heavy[0]:g}, {heavy[0] / light[0]:.1e} times more: beyond the {WEIGHT_SPAN:.0e} the solver "
                "resolves in one level, the lighter term no longer acts with the weight it states", light[2],
                "give the lighter term its own later level (`priority 2`) instead of a tiny weight, or bring the "
                "weights closer", f"priority level {level}",
                {"level": level, "light": light[0], "heavy": heavy[0], "phase": phase}))
    return findings


def unused(task: ir.Task) -> list[Finding]:
    frames, inputs, params = set(), set(), set()
    for statement in [*task.constraints, *task.objectives]:
        if isinstance(statement, ir.Constraint) and statement.frame:
            frames.add(statement.frame)
        for arg in (leaf for value in statement.args.values() for leaf in derived.leaves(value)):
            if isinstance(arg, ir.FrameRef):
                frames.add(arg.name)
            elif isinstance(arg, ir.InputRef):
                inputs.add(arg.name)
            elif isinstance(arg, ir.ParamRef):
                params.add(arg.name)
    params |= {task.param(name).frame for name in params if task.param(name).frame}
    frames |= {f.base for f in task.frames if f.base}          # `frame b = a ...` uses a (b is judged itself)
    findings = []
    for kind, decls, used in (("frame", task.frames, frames), ("input", task.inputs, inputs),
                              ("param", task.params, params)):
        for decl in decls:
            if decl.name not in used:
                findings.append(Finding("unused-declaration", Severity.WARNING,
                                        f"{kind} '{decl.name}' is declared but nothing uses it", decl.span,
                                        "remove it, or use it in a constraint or objective", f"{kind} {decl.name}",
                                        {"kind": kind, "name": decl.name}))
    return findings


def _geometric(rows: list[ConstraintRows]) -> list[ConstraintRows]:
    return [r for r in rows if not r.constraint.soft and not CONSTRAINTS[r.constraint.primitive].rate]


def redundant(rows: list[ConstraintRows], nq: int, reached: list = (), rows_at=None) -> list[Finding]:
    """VF802 and VF804 over the region the task reaches: the start and the states of ``reached`` (states of
    check's random walk; ``rows_at(q)`` gives the rows there). A constraint is redundant when it has a bounded
    row at one of these states at least, and at each such state the others imply its bounded rows. A state
    where every row of it is unbounded (inactive) is no evidence: inactive at all of them, it gets a note
    (VF804), never VF802. A constraint with a degenerate row (zero gradient: the row measures nothing about
    the motion, e.g. ``tilt_at_most`` exactly on its axis) at any of these states is never called redundant:
    what it adds shows only away from that point."""
    reached = list(reached)
    if len(reached) > REDUNDANCY_STATES:        # evenly spaced, the last included: bounded LPs at any --samples
        picks = np.linspace(0, len(reached) - 1, REDUNDANCY_STATES).round().astype(int)
        reached = [reached[k] for k in picks]
    kept = _geometric(rows)
    states = [{r.index: r for r in rows}] + [None] * len(reached)

    def at(k: int) -> dict[int, ConstraintRows]:
        if states[k] is None:
            states[k] = {r.index: r for r in rows_at(reached[k - 1])}
        return states[k]

    region = f"at the start and at {len(reached)} states the task reaches under random input" if reached \
        else "at the start"
    findings = []
    for r in reversed([r for r in kept if not r.bounds and len(r.A)]):
        acting = [k for k in range(len(states)) if at(k)[r.index].bounded.any()]
        if not acting:
            findings.append(Finding(
                "inactive-constraint", Severity.NOTE,
                f"inactive {region}: every row of this constraint is unbounded there (such as `0 >= -inf` for "
                f"a mesh beyond reach) and holds whatever the motion; it acts only where the tool comes closer. "
                f"Inactive is not redundant: whether the others imply it was not tested",
                r.constraint.span, "to see it act, check from a start where it binds (--scene), or simulate",
                subject(r.constraint), {"states": len(states)}))
            continue
        others = [o for o in kept if o is not r]
        if not all(_implied_at(at(k)[r.index], [at(k)[o.index] for o in others], nq) for k in acting):
            continue
        kept = others
        names = ", ".join(f"{describe(o.constraint)} at {where(o.constraint)}" for o in others) or "the joint limits"
        everywhere = len(acting) == len(states)
        scope = region if everywhere else (f"{region}, at the {len(acting)} of these {len(states)} where it has "
                                           f"a bounded row (inactive at the others),")
        hint = "remove it, or check its reference and tolerance" if everywhere else \
            (f"it acts at only {len(acting)} of the {len(states)} states: check from a start where it binds "
             f"(--scene) before removing it, or check its reference and tolerance")
        findings.append(Finding("redundant-constraint", Severity.WARNING,
                                f"{scope} every row of this constraint is implied by the others ({names}): "
                                f"it adds nothing there", r.constraint.span, hint, subject(r.constraint),
                                {"implied_by": [where(o.constraint) for o in others], "states": len(states),
                                 "acting_states": len(acting)}))
    return findings


def _implied_at(r: ConstraintRows, others: list[ConstraintRows], nq: int) -> bool:
    """At one state: r has no degenerate row, the others can hold, and they keep every row of r."""
    if _degenerate(r):
        return False
    system = LinearSystem.from_rows(others, nq)
    return system.feasible() and _implied(r, system)


def _degenerate(r: ConstraintRows) -> bool:
    """A bounded row with (numerically) zero gradient: it says nothing about the motion at this state."""
    scale = max(1.0, float(np.max(np.abs(r.A)))) if r.A.size else 1.0
    norms = np.linalg.norm(r.A, axis=1)
    return bool(np.any(r.bounded & (norms <= DEGENERATE * scale)))


def _implied(r: ConstraintRows, others: LinearSystem) -> bool:
    for a, lb, ub in zip(r.A, r.lb, r.ub):
        if lb > -float("inf") and -others.reach(-a) < lb - IMPLIED:
            return False
        if ub < float("inf") and others.reach(a) > ub + IMPLIED:
            return False
    return True


def contradictory(rows: list[ConstraintRows], nq: int) -> list[Finding]:
    findings = []
    candidates = [r for r in _geometric(rows) if not r.bounds and len(r.A)]
    for a, b in itertools.combinations(candidates, 2):
        t, _ = LinearSystem.from_rows([a, b], nq).margin()
        if t >= FEASIBLE:
            continue
        findings.append(Finding(
            "contradictory-tolerances", Severity.ERROR,
            f"this constraint and {describe(b.constraint)} at {where(b.constraint)} cannot both hold at the start, "
            f"whatever the joints do: their tolerances leave no common motion (they miss by {-t:.3g}, m or rad)",
            a.constraint.span, "widen one of the tolerances, or fix one of the references", subject(a.constraint),
            {"other": where(b.constraint), "miss": -t}))
    return findings
