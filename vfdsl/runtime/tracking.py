"""The tracking readout: for every part of every `track` term, the rate the user commanded, the rate the tick's
answer gives, and, when that is less, what holds it (constraint rows at their bounds, joints at their limits).

    for t in ctrl.tracking(q, {"hand": [2, 0, 0]}):
        print(t)          # track(tip) linear: 2 mm/s asked, 1.99 mm/s (99.5 %) ...
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import casadi as ca
import numpy as np

ACTIVE = 1e-9
"""A row or bound within ACTIVE (row units per tick) of its bound counts as holding the motion back."""
FOLLOWED = 0.99
"""A tracked part reaching FOLLOWED of its command is not reported as limited."""


@dataclass(frozen=True)
class Tracking:
    """One tracked part: ``commanded`` and ``achieved`` rates (m/s or rad/s, world frame), ``fraction`` the
    achieved rate along the commanded one (nan with no command), ``limits`` what holds it back (labels), empty
    when it follows (>= 99 %) or nothing in the tick is at its bound."""

    term: str
    commanded: np.ndarray
    achieved: np.ndarray
    fraction: float
    limits: list[str]

    def __str__(self) -> str:
        unit = "rad/s" if self.term.endswith("angular") else "m/s"
        text = (f"{self.term}: {np.linalg.norm(self.commanded):.4g} {unit} asked, "
                f"{np.linalg.norm(self.achieved):.4g} {unit} achieved")
        if np.isfinite(self.fraction):
            text += f" ({self.fraction:.1%} along the command)"
        return text + ("; held by " + "; ".join(self.limits) if self.limits else "")


def tracked_terms(task, problem) -> tuple[list[str], list[str | None], ca.Function]:
    """The names of the tracked parts (a phase's: "... in phase NAME"), each one's phase (None: held in every
    phase) and a Function (q, u, p, dt) -> (E_1, f_1, E_2, f_2, ...) of their rows (dq -> rate, per tick divided
    by dt) and commanded rates."""
    ctx = problem.context
    names, phases, outputs = [], [], []
    owned = [(o, None) for o in task.objectives] + [(o, ph.name) for ph in task.phases for o in ph.objectives]
    for objective, phase in owned:
        if objective.term != "track":
            continue
        for term in importlib.import_module("vfdsl.objectives.track").lower(objective, ctx):
            frame = objective.args.get("frame")
            where = f" in phase {phase}" if phase else ""
            names.append(f"track({getattr(frame, 'name', '')}){' ' + term.part if term.part else ''}{where}")
            phases.append(phase)
            outputs += [ca.densify(term.E), ca.densify(term.f)]
    return names, phases, ca.Function("tracked", [ctx.q, ctx.u, ctx.p, ctx.dt], outputs)


def readout(names, rows, x, nq, dt, qp, shown=None) -> list[Tracking]:
    """The readout of one tick from the tracked parts' rows (``rows``: E_1, f_1, ...), the answer x = [dq; s] and
    the tick's QuadraticProgram (its rows and bounds name the limits); ``shown``: which parts to read (all: None)."""
    dq = np.asarray(x[:nq])
    n = qp.P.shape[0]
    Ax = qp.A @ np.asarray(x)
    at_bound = (np.abs(Ax - qp.lb) <= ACTIVE) | (np.abs(Ax - qp.ub) <= ACTIVE)
    held = [qp.labels[i] for i in np.flatnonzero(at_bound) if i >= n or i < nq]    # not slack >= 0
    found = []
    for k, name in enumerate(names):
        if shown is not None and not shown[k]:
            continue
        E, f = np.array(rows[2 * k]), np.array(rows[2 * k + 1]).ravel()
        achieved = E @ dq / dt
        fraction = float(achieved @ f / (f @ f)) if f @ f > 0 else float("nan")
        limited = np.isfinite(fraction) and fraction < FOLLOWED
        found.append(Tracking(name, f, achieved, fraction, held if limited else []))
    return found
