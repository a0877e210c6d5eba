"""Each ``require`` and ``minimize`` of a task on its own, numerically, at a state of the robot.

The assembled QP (:mod:`vfdsl.compiler.assemble`) merges the statements: joint bounds are intersected
and soft rows get slacks. The analyses need every statement separately (which constraint conflicts with
which, which objective term drives a motion), so this module lowers each one again with the same
primitive and objective modules and the same symbols, into one CasADi Function per statement:

    constraint i:  lb_i <= A_i dq <= ub_i        (rows on the state after the step, SI units: m or rad)
    objective k:   w_k || E_k dq - f_k ||^2

At rest (dq = 0) a constraint's rows measure the state itself: ``max(lb, -ub)`` over its rows is how far
outside its tolerance the frame is now (0 or negative when inside).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from vfdsl.compiler import registry
from vfdsl.compiler.assemble import urdf_speed_limits
from vfdsl.compiler.context import Context
from vfdsl.ir import model as ir
from vfdsl.runtime.values import ASSUMED_PERIOD



@dataclass(frozen=True)
class ConstraintRows:
    """One constraint's rows lb <= A dq <= ub at a state; ``bounds``: A is (a selection of) the identity."""

    index: int
    constraint: ir.Constraint
    A: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    facets: list[str]
    bounds: bool

    @property
    def bounded(self) -> np.ndarray:
        """Which rows have a finite side at this state. The others (lb = -inf, ub = inf: ``0 >= -inf`` for a
        mesh feature beyond reach) hold whatever the motion: inactive here, which says nothing about elsewhere."""
        return np.isfinite(self.lb) | np.isfinite(self.ub)

    @property
    def violation_at_rest(self) -> float:
        """How much the rows are violated with no motion (dq = 0); <= 0 when the state satisfies them."""
        if not len(self.lb):
            return -np.inf
        return float(max(np.max(self.lb), np.max(-self.ub)))


@dataclass(frozen=True)
class ObjectiveTerm:
    index: int
    objective: ir.Objective
    E: np.ndarray
    f: np.ndarray


class Linearization:
    """Per-statement rows and terms of ``task``, built on the symbols of ``context``."""

    def __init__(self, task: ir.Task, context: Context):
        self.task = task
        self.context = context
        self.robot = context.robot
        symbols = [context.q, context.u, context.p, context.dt]
        self._rows, self._facets, self._is_bounds = [], [], []
        for c in task.constraints:
            rows = registry.constraint(c.primitive).lower(c, context)
            self._rows.append(ca.Function("rows", symbols, [ca.densify(ca.SX(x)) for x in (rows.A, rows.lb, rows.ub)]))
            self._facets.append(list(rows.facets))
            self._is_bounds.append(rows.A.shape[0] > 0 and _is_selection(rows.A))
        self._terms = []            # (objective index, its term's E and f as a Function)
        for k, o in enumerate(task.objectives):
            for term in registry.objective(o.term).lower(o, context):
                self._terms.append((k, ca.Function("term", symbols, [ca.densify(ca.SX(term.E)),
                                                                     ca.densify(ca.SX(term.f))])))
        self.default_params = context.layout.defaults.copy()
        self.period = task.scene.period or ASSUMED_PERIOD
        self.n_inputs = context.u.shape[0]
        self.speed_limits = urdf_speed_limits(task, self.robot)

    def speed_bound(self, dt=None) -> np.ndarray | None:
        """|dq| per joint in one tick under the URDF's velocity limits, which the controller holds every tick to
        when the task states no ``joint_speed()`` (:func:`~vfdsl.compiler.assemble.urdf_speed_limits`); None when
        it states its own, whose rows are among :meth:`rows`."""
        return None if self.speed_limits is None else self.speed_limits * (self.period if dt is None else dt)

    def _args(self, q, u, p, dt):
        u = np.zeros(self.n_inputs) if u is None else u
        p = self.default_params if p is None else p
        return [np.asarray(q, dtype=float), u, p, self.period if dt is None else dt]

    def rows(self, q, u=None, p=None, dt=None) -> list[ConstraintRows]:
        """Every constraint's rows at joint coordinates ``q`` (zero inputs, default params, the period)."""
        args = self._args(q, u, p, dt)
        out = []
        for i, (c, function) in enumerate(zip(self.task.constraints, self._rows)):
            A, lb, ub = (np.array(v) for v in function(*args))
            out.append(ConstraintRows(i, c, A.reshape(-1, self.robot.nq), lb.ravel(), ub.ravel(),
                                      self._facets[i], self._is_bounds[i]))
        return out

    def terms(self, q, u=None, p=None, dt=None) -> list[ObjectiveTerm]:
        args = self._args(q, u, p, dt)
        out = []
        for k, function in self._terms:
            E, f = (np.array(v) for v in function(*args))
            out.append(ObjectiveTerm(k, self.task.objectives[k], E.reshape(-1, self.robot.nq), f.ravel()))
        return out


def _is_selection(A) -> bool:
    """A constant matrix whose rows are distinct unit rows (per-joint bounds)."""
    if not ca.SX(A).is_constant():
        return False
    M = np.array(ca.DM(A))
    return bool(np.all((M == 0) | (M == 1)) and np.all(M.sum(axis=1) == 1))
