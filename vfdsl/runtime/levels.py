"""What a tick solves, level by level: the priority levels of :meth:`Controller.problem` and the tracking readout
of :meth:`Controller.tracking`.

A task's objective comes in priority levels (docs/language.md, "Weights and priorities"). ``step()`` solves them
in one call of DAQP's hierarchical mode: level j minimizes its own cost 1/2 |R_j x - r_j|^2 over the rows and
bounds of the tick and over the optimal set of every level above it (docs/runtime.md, "Priority levels"). The sum
of the levels' costs (``QuadraticProgram.P``, ``.g``) is what the least-violation phase uses; it is not the problem
``step()`` solves on a feasible tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfdsl.compiler.assemble import HESSIAN_FLOOR


@dataclass(frozen=True)
class PriorityLevel:
    """One priority level of a tick's QP, over x = [dq; slacks].

    ``terms`` names what it solves ("track(tip) linear", "damping()"); ``R``, ``r`` its rows and targets, its cost
    being 1/2 |R x - r|^2 = 1/2 x'Px + g'x + const with P = R'R + floor I, g = -R'r (the terms' weights applied:
    R = sqrt(2 w) E per term; no scaling of the solver's)."""

    index: int
    terms: list[str]
    R: np.ndarray
    r: np.ndarray

    @property
    def P(self) -> np.ndarray:
        return self.R.T @ self.R + HESSIAN_FLOOR * np.eye(self.R.shape[1])

    @property
    def g(self) -> np.ndarray:
        return -self.R.T @ self.r

    def cost(self, x) -> float:
        """This level's cost 1/2 x'Px + g'x at x (a full x = [dq; slacks], or dq when the task has no soft
        constraints)."""
        x = np.asarray(x, dtype=float)
        return float(0.5 * x @ self.P @ x + self.g @ x)


def priority_levels(outputs: list, names: list[list[str]]) -> list[PriorityLevel]:
    """The levels of one evaluation of ``qp_data`` (its outputs as numpy arrays): (Rj, rj) per level after the 7
    outputs of the whole QP; a task of one level has none (its cost is the whole QP's)."""
    return [PriorityLevel(j + 1, list(names[j]), outputs[7 + 2 * j], outputs[8 + 2 * j].ravel())
            for j in range((len(outputs) - 7) // 2)]
