"""What a tick solves, level by level: the priority levels of :meth:`Controller.problem` and the tracking readout
of :meth:`Controller.tracking`.

A task's objective comes in priority levels (docs/language.md, "Weights and priorities"). ``step()`` solves them
in order: level j minimizes its own cost 1/2 x'P_j x + g_j'x over the rows and bounds of the tick, while the
rows E_i x of every level i above it stay within ``band`` of their values at level i's answer
(docs/runtime.md, "Priority levels"). The sum of the levels' costs (``QuadraticProgram.P``, ``.g``) is what the
least-violation phase uses; it is not the problem ``step()`` solves on a feasible tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PriorityLevel:
    """One priority level of a tick's QP, over x = [dq; slacks].

    ``terms`` names what it solves ("track(tip) linear", "damping()"); ``P``, ``g`` its cost 1/2 x'Px + g'x (the
    terms' weights applied, plus the Hessian floor; no scaling or regularization of the solver's); ``E`` the
    stacked rows of its terms, which the levels below hold within ``band`` (m or rad per tick) of their values
    at this level's answer."""

    index: int
    terms: list[str]
    P: np.ndarray
    g: np.ndarray
    E: np.ndarray
    band: float

    def cost(self, x) -> float:
        """This level's cost at x (a full x = [dq; slacks], or dq when the task has no soft constraints)."""
        x = np.asarray(x, dtype=float)
        return float(0.5 * x @ self.P @ x + self.g @ x)


def priority_levels(outputs: list, names: list[list[str]], band: float) -> list[PriorityLevel]:
    """The levels of one evaluation of ``qp_data`` (its outputs as numpy arrays): (Hj, gj, Ej) per level after
    the 7 outputs of the whole QP, or the whole QP as one level."""
    if len(outputs) == 7:
        H, g = outputs[0], outputs[1]
        return [PriorityLevel(1, list(names[0]) if names else [], H, g.ravel(), np.zeros((0, H.shape[0])), band)]
    return [PriorityLevel(j + 1, list(names[j]), outputs[7 + 3 * j], outputs[8 + 3 * j].ravel(), outputs[9 + 3 * j],
                          band)
            for j in range((len(outputs) - 7) // 3)]
