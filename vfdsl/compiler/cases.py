"""A procedure's QP per phase: the rows and terms a tick evaluates and solves (issue 33: "a tick within 1.3x of the
same task's single-phase tick").

The assembled ``qp_data`` of a procedure (:mod:`vfdsl.compiler.assemble`) holds every phase's rows and terms, an
idle phase's rows with infinite bounds and its terms with weight 0. A tick needs less, and which part depends on the
activity (:mod:`vfdsl.compiler.phases`): phase k is current when its hard flag h_k is 1, and *steady* when its
weight is exactly 1, every other weight 0 and every funnel width 0 (no blend running); else it is *blending*.

- **Steady in phase k**: the assembled QP without the rows whose bounds are infinite while phase k is current (it
  keeps the rows held in every phase, phase k's hard rows and every soft row: a soft constraint's slack is a
  variable of every case), with the assembled QP's values at that activity (weights and hard flags one-hot at k,
  widths 0) substituted: the other phases' terms are then structurally zero and are left out, their rows of each
  priority level and the levels left empty (so a phase whose only term is damping solves one plain QP, as the same
  task with that phase alone does).
- **Blending** (any phase): the assembled QP itself, every row and term, switched by the activity's values. A blend
  lasts the declared blend time after a transition (200 ms in the example); one case for all of them keeps the
  generated code (and its compile time) near P + 1 times a phase's, not 2P.

Each case gives the assembled QP's answer at the activities it serves: the rows it leaves out have infinite bounds
(no solution violates them, no solver holds them) and the terms it leaves out are zero. The run time picks the case
from the activity (:func:`case_index`, :func:`vfdsl.runtime.qp.build_procedure_step`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from vfdsl.compiler.assemble import QP_OUTPUTS, AssembledProblem, output_names
from vfdsl.ir import model as ir

LEVELS_FROM = len(QP_OUTPUTS)
"""qp_data's outputs from this index on are the priority levels' (R_j, r_j) pairs (:mod:`vfdsl.compiler.assemble`)."""


@dataclass(frozen=True)
class PhaseCase:
    """Phase ``phase``'s steady QP, or (``phase`` None, ``steady`` False) the blending one: ``function`` (qp_data's arguments; its A, lba and uba hold
    ``rows`` only, the assembled QP's row indices in order) and ``last_level_is_damping`` (as
    :attr:`AssembledProblem.last_level_is_damping`, for its levels)."""

    phase: str | None
    steady: bool
    function: ca.Function
    rows: tuple[int, ...]
    last_level_is_damping: bool


def phase_rows(problem: AssembledProblem, phase: str) -> tuple[int, ...]:
    """The rows of the assembled QP that phase ``phase`` can hold: those of every phase, its hard rows, the soft
    rows."""
    return tuple(i for i, label in enumerate(problem.row_labels)
                 if label.phase is None or label.soft or label.phase == phase)


def case_index(activity: ca.MX, n_phases: int) -> ca.MX:
    """The case of this tick's activity (2P weights and hard flags, then the funnel widths): k for phase k steady,
    P for any blending tick (:func:`phase_cases`' order)."""
    weights, flags, widths = activity[:n_phases], activity[n_phases:2 * n_phases], activity[2 * n_phases:]
    phase = ca.dot(ca.DM(range(n_phases)), flags)
    others = ca.mmax(weights * (1 - flags))               # the largest weight of another phase (weights >= 0)
    steady = ca.logic_and(ca.dot(flags, weights) == 1, others == 0)
    if widths.numel():
        steady = ca.logic_and(steady, ca.mmax(ca.fabs(widths)) == 0)
    return ca.if_else(steady, phase, n_phases)


def phase_cases(problem: AssembledProblem, task: ir.Task) -> list[PhaseCase]:
    """The steady case of each phase, in phase order, then the blending case (every row and term)."""
    fn = problem.function
    phases = [p.name for p in task.phases]
    n = len(phases)
    symbols = [ca.SX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    outputs = fn.call(symbols)
    activity = symbols[fn.index_in("activity")]
    cases = []
    for k, phase in enumerate(phases):
        rows = phase_rows(problem, phase)
        one_hot = ca.DM.zeros(activity.numel())
        one_hot[k] = one_hot[n + k] = 1.0
        at_rest = [ca.substitute(v, activity, one_hot) for v in outputs]
        kept, last = _levels_left(_rows_of(at_rest, fn, rows), problem.last_level_is_damping)
        cases.append(PhaseCase(phase, True, ca.Function(f"qp_data_{phase}", symbols, kept, fn.name_in(),
                                                        output_names((len(kept) - LEVELS_FROM) // 2)), rows, last))
    return cases + [PhaseCase(None, False, fn, tuple(range(len(problem.row_labels))), problem.last_level_is_damping)]


def _rows_of(outputs: list[ca.SX], fn: ca.Function, rows: tuple[int, ...]) -> list[ca.SX]:
    """qp_data's outputs with A, lba and uba of ``rows`` only."""
    kept = list(outputs)
    for name in ("A", "lba", "uba"):
        i = fn.index_out(name)
        kept[i] = outputs[i][list(rows), :]
    return kept


def _levels_left(outputs: list[ca.SX], last_is_damping: bool) -> tuple[list[ca.SX], bool]:
    """The outputs without each level's rows that are structurally zero with a zero target, and without the levels
    left empty (one level left: no levels, H and g being its cost); whether the last level is still damping."""
    levels = []
    pairs = list(zip(outputs[LEVELS_FROM::2], outputs[LEVELS_FROM + 1::2]))
    for j, (R, r) in enumerate(pairs):
        rows = [i for i in range(R.size1()) if not (r[i].is_zero() and all(R[i, c].is_zero()
                                                                             for c in range(R.size2())))]
        if rows:
            levels.append((R[rows, :], r[rows], j == len(pairs) - 1))
    if len(levels) < 2:
        return outputs[:LEVELS_FROM], False
    return (outputs[:LEVELS_FROM] + [v for R, r, _ in levels for v in (R, r)],
            last_is_damping and levels[-1][2])

