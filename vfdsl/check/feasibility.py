"""Feasibility at the start: can every hard constraint hold together with the joint limits and speeds?

The hard rows of every constraint, linearized at the scene's start configuration (zero input, default
params, the scene's period), form a :class:`~vfdsl.check.lp.LinearSystem`, within the URDF's velocity limits
over one tick when the task states no joint_speed (the controller holds every tick to them: ``speed``); its
margin LP (HiGHS) says whether one tick can satisfy them all. When it cannot, a deletion filter over constraint
groups (one group per source constraint) finds an irreducible infeasible subset: drop each group in turn, keep it
dropped when the rest stays infeasible; what remains conflicts, and removing any one of it resolves it.
"""

from __future__ import annotations

import numpy as np

from vfdsl.check.linearized import ConstraintRows
from vfdsl.ir.constraints import describe, subject, where
from vfdsl.check.lp import LinearSystem
from vfdsl.check.report import Finding, Severity


def hard(rows: list[ConstraintRows]) -> list[ConstraintRows]:
    return [r for r in rows if not r.constraint.soft]


def margin(rows: list[ConstraintRows], nq: int, speed: np.ndarray | None = None) -> float:
    """The feasibility margin over the hard rows (m or rad; negative: infeasible), |dq| within ``speed``."""
    return LinearSystem.from_rows(hard(rows), nq, speed).margin()[0]


def irreducible_infeasible_subset(rows: list[ConstraintRows], nq: int,
                                  speed: np.ndarray | None = None) -> list[ConstraintRows]:
    """A minimal set of constraints whose rows cannot hold together within ``speed`` (deletion filter; [] if
    feasible). The speed bound stays: it is not a statement that could be removed."""
    kept = hard(rows)
    if LinearSystem.from_rows(kept, nq, speed).feasible():
        return []
    for group in list(kept):
        trial = [r for r in kept if r is not group]
        if not LinearSystem.from_rows(trial, nq, speed).feasible():
            kept = trial
    return kept


def within(speed: np.ndarray | None) -> str:
    """How a finding says the motion was bounded: the URDF's velocity limits when the task states no
    joint_speed, else nothing (the task's joint_speed is among the constraints named)."""
    return "" if speed is None else " within the URDF's velocity limits (the task states no joint_speed)"


def analyse(rows: list[ConstraintRows], nq: int, figures: dict, speed: np.ndarray | None = None) -> list[Finding]:
    t, _ = LinearSystem.from_rows(hard(rows), nq, speed).margin()
    figures["start_margin"] = t
    if t >= -1e-10:
        return []
    conflict = irreducible_infeasible_subset(rows, nq, speed)
    names = [f"{describe(r.constraint)} at {where(r.constraint)}" for r in conflict]
    first = conflict[0].constraint if conflict else None
    return [Finding(
        "start-infeasible", Severity.ERROR,
        f"at the start configuration no joint motion{within(speed)} satisfies every hard constraint within one "
        f"tick (the smallest uniform violation that makes them hold is {-t:.3g}, in the rows' units: m or rad); "
        + (f"these {len(conflict)} conflict: " if len(conflict) != 1 else "this one cannot hold: ") + "; ".join(names),
        first.span if first else None,
        "remove or relax one of them (a looser tolerance, a soft constraint, a higher joint_speed fraction), "
        "or start where they agree" + ("" if speed is None else " (nearer: one tick moves each joint at most its "
                                       "URDF velocity limit times the period)"),
        subject(first) if first else "task",
        {"margin": t, "conflict": [{"constraint": describe(r.constraint), "where": where(r.constraint),
                                    "file": r.constraint.span.file, "line": r.constraint.span.line}
                                   for r in conflict]})]
