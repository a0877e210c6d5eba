"""The pieces lowerings produce: constraint rows lb <= A dq <= ub, and objective terms || E dq - f ||^2.

Every geometric row comes from an inequality u . (delta + dx) <= eps on the state after the step; as
H dx >= h this is H = -u, h = -eps + u . delta (DESIGN; the seed's eq. 4 has the sign of H delta wrong).
:func:`facets` builds such rows from the directions u (one per row) acting on dx = J dq.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Rows:
    """Rows lb <= A dq <= ub of one constraint; ``facets`` names each row; ``bounds``: A is the identity
    (per-joint bounds, which the assembly may hand to the solver as variable bounds)."""

    A: ca.SX
    lb: ca.SX
    ub: ca.SX
    facets: list[str]
    bounds: bool = False


@dataclass(frozen=True)
class Term:
    """An objective term || E dq/dt - f ||^2: E dq/dt a rate of the task (m/s, rad/s, 1/s) and f the rate asked
    for, so that a weight is a plain number whatever the control period (the weight is applied by the assembly).

    ``part`` names it in labels ("linear"); ``after`` = 1 puts it just below its statement's priority level (the
    part of `track` that yields to the other)."""

    E: ca.SX
    f: ca.SX
    part: str = ""
    after: int = 0


def toward(error, time_constant, dt):
    """The rate that closes ``error`` with ``time_constant``: error / tau, but never more than the whole error in
    one tick (error / dt), so a time constant below the period cannot overshoot."""
    return error / ca.fmax(time_constant, dt)


def facets(U, delta, eps, J, name: str = "facet") -> Rows:
    """Rows u_i . (delta + J dq) <= eps for each row u_i of U:  -U J dq >= -eps + U delta."""
    k = U.shape[0]
    return Rows(A=-U @ J, lb=-eps + U @ delta, ub=ca.SX(ca.DM.inf(k)),
                facets=[f"{name} {i + 1}/{k}" for i in range(k)])


def lower_bounds(A, h, labels: list[str]) -> Rows:
    """One-sided rows A dq >= h."""
    return Rows(A=A, lb=h, ub=ca.SX(ca.DM.inf(A.shape[0])), facets=labels)
