"""Feasibility at the start: can every hard constraint hold together with the joint limits and speeds?

The hard rows of every constraint, linearized at the scene's start configuration (zero input, default
params, the scene's period), form a :class:`~vfdsl.check.lp.LinearSystem`; its margin LP (HiGHS) says
whether one tick can satisfy them all. When it cannot, a deletion filter over constraint groups (one
group per source constraint) finds an irreducible infeasible subset: drop each group in turn, keep it
dropped when the rest stays infeasible; what remains conflicts, and removing any one of it resolves it.
"""

from __future__ import annotations

from vfdsl.check.linearized import ConstraintRows
from vfdsl.ir.constraints import describe, subject, where
from vfdsl.check.lp import LinearSystem
from vfdsl.check.report import Finding, Severity


def hard(rows: list[ConstraintRows]) -> list[ConstraintRows]:
    return [r for r in rows if not r.constraint.soft]


def margin(rows: list[ConstraintRows], nq: int) -> float:
    """The start's feasibility margin over the hard rows (m or rad; negative: infeasible)."""
    return LinearSystem.from_rows(hard(rows), nq).margin()[0]


def irreducible_infeasible_subset(rows: list[ConstraintRows], nq: int) -> list[ConstraintRows]:
    """A minimal set of constraints whose rows cannot hold together (deletion filter; [] if feasible)."""
    kept = hard(rows)
    if LinearSystem.from_rows(kept, nq).feasible():
        return []
    for group in list(kept):
        trial = [r for r in kept if r is not group]
        if not LinearSystem.from_rows(trial, nq).feasible():
            kept = trial
    return kept


def analyse(rows: list[ConstraintRows], nq: int, figures: dict) -> list[Finding]:
    t, _ = LinearSystem.from_rows(hard(rows), nq).margin()
    figures["start_margin"] = t
    if t >= -1e-10:
        return []
    conflict = irreducible_infeasible_subset(rows, nq)
    names = [f"{describe(r.constraint)} at {where(r.constraint)}" for r in conflict]
    first = conflict[0].constraint if conflict else None
    return [Finding(
        "start-infeasible", Severity.ERROR,
        f"at the start configuration no joint motion satisfies every hard constraint within one tick "
        f"(the smallest uniform violation that makes them hold is {-t:.3g}, in the rows' units: m or rad); "
        f"these {len(conflict)} conflict: " + "; ".join(names),
        first.span if first else None,
        "remove or relax one of them (a looser tolerance, a soft constraint, a higher joint_speed fraction), "
        "or start where they agree",
        subject(first) if first else "task",
        {"margin": t, "conflict": [{"constraint": describe(r.constraint), "where": where(r.constraint),
                                    "file": r.constraint.span.file, "line": r.constraint.span.line}
                                   for r in conflict]})]
