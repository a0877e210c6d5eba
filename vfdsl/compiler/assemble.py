"""Assembly: a checked task -> one CasADi Function giving the QP of a control tick.

    qp_data(q, u, p, dt) -> (H, g, A, lba, uba, lbx, ubx)

is the QP in CasADi conic's standard form over x = [dq; s] (s: one slack per soft constraint):

    minimize 1/2 x' H x + g' x   subject to   lba <= A x <= uba,   lbx <= x <= ubx

- objective: H = 2 sum_k w_k E_k' E_k + 2 diag(w_c) on the slacks + rho I (a tiny floor that keeps H
  positive definite when the terms leave some joint motion free), g = -2 sum_k w_k E_k' f_k;
- hard rows that bound one joint each (joint limits, joint speeds) become the variable bounds lbx, ubx
  (their intersection); every other hard row is a row of A;
- a soft constraint's rows get its slack: A dq + s >= lb (and A dq - s <= ub for two-sided rows), s >= 0,
  with cost w_c s^2.

Every row of A and every variable bound keeps a :class:`RowLabel` naming its primitive, frame, facet and
source line (and the fixture ``use`` sites it came through).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from vfdsl.compiler.context import Context
from vfdsl.compiler.rows import Rows
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.syntax.ast import Span

HESSIAN_FLOOR = 1e-9


@dataclass(frozen=True)
class RowLabel:
    """Where a row of the QP comes from."""

    primitive: str
    frame: str | None
    facet: str
    span: Span
    via: tuple[Span, ...] = ()
    soft: bool = False

    def __str__(self) -> str:
        on = f"({self.frame})" if self.frame else ""
        kind = "soft " if self.soft else ""
        where = f"{self.span.file}:{self.span.line}"
        through = "".join(f" via {s.file}:{s.line}" for s in self.via)
        return f"{kind}{self.primitive}{on} {self.facet} [{where}{through}]"


@dataclass
class AssembledProblem:
    """The tick's QP as a CasADi Function, with the layout of its inputs and the labels of its rows."""

    function: ca.Function
    context: Context
    row_labels: list[RowLabel]
    row_groups: list[int]                    # per row of A, the index of the constraint it comes from
    bound_labels: list[list[RowLabel]]       # per variable, the hard bounds that shaped it (may be empty)
    slack_labels: list[RowLabel] = field(default_factory=list)

    @property
    def nq(self) -> int:
        return self.context.nq

    @property
    def n_slack(self) -> int:
        return len(self.slack_labels)


def _module(kind: str, name: str):
    return importlib.import_module(f"vfdsl.{kind}.{name}")


def _label(c: ir.Constraint, facet: str) -> RowLabel:
    return RowLabel(c.primitive, c.frame, facet, c.span, tuple(c.via), c.soft)


def assemble(task: ir.Task, robot: Robot) -> AssembledProblem:
    ctx = Context(task, robot)
    nq = ctx.nq
    inf = ca.DM.inf(1)

    # objective over dq
    H = HESSIAN_FLOOR * ca.SX.eye(nq)
    g = ca.SX.zeros(nq)
    for objective in task.objectives:
        term = _module("objectives", objective.term).lower(objective, ctx)
        H += 2 * objective.weight * (term.E.T @ term.E)
        g -= 2 * objective.weight * (term.E.T @ term.f)

    lbx, ubx = [-inf] * nq, [inf] * nq
    bound_labels: list[list[RowLabel]] = [[] for _ in range(nq)]
    rows_A, rows_lb, rows_ub, labels, groups = [], [], [], [], []
    soft_rows: list[tuple[int, Rows, ir.Constraint, int]] = []
    for number, c in enumerate(task.constraints):
        rows = _module("primitives", c.primitive).lower(c, ctx)
        if c.soft:
            soft_rows.append((len(soft_rows), rows, c, number))
        elif rows.bounds:
            for i in range(nq):
                lbx[i] = ca.fmax(lbx[i], rows.lb[i])
                ubx[i] = ca.fmin(ubx[i], rows.ub[i])
                bound_labels[i].append(_label(c, rows.facets[i]))
        else:
            rows_A.append(rows.A)
            rows_lb.append(rows.lb)
            rows_ub.append(rows.ub)
            labels += [_label(c, f) for f in rows.facets]
            groups += [number] * len(rows.facets)

    # soft constraints: one slack each, appended after dq
    n_slack = len(soft_rows)
    H = ca.diagcat(H, ca.diag(ca.DM([2 * c.weight for _, _, c, _ in soft_rows]))) if n_slack else H
    g = ca.vertcat(g, ca.DM.zeros(n_slack))
    A_full = [ca.horzcat(A, ca.SX.zeros(A.shape[0], n_slack)) for A in rows_A]
    slack_labels = []
    for index, rows, c, number in soft_rows:
        column = ca.DM.zeros(1, n_slack)
        column[index] = 1
        k = rows.A.shape[0]
        one_sided = rows.ub.is_constant() and bool(np.all(np.isinf(np.array(ca.DM(rows.ub)))))
        A_full.append(ca.horzcat(rows.A, ca.repmat(column, k, 1)))
        rows_lb.append(rows.lb)
        rows_ub.append(ca.DM.inf(k))
        labels += [_label(c, f + " (lower)" if not one_sided else f) for f in rows.facets]
        groups += [number] * k
        if not one_sided:
            A_full.append(ca.horzcat(rows.A, ca.repmat(-column, k, 1)))
            rows_lb.append(-ca.DM.inf(k))
            rows_ub.append(rows.ub)
            labels += [_label(c, f + " (upper)") for f in rows.facets]
            groups += [number] * k
        slack_labels.append(_label(c, "slack"))
    lbx += [ca.DM(0.0)] * n_slack
    ubx += [inf] * n_slack

    A = ca.vertcat(*A_full) if A_full else ca.SX(0, nq + n_slack)
    lba = ca.vertcat(*rows_lb) if rows_lb else ca.SX(0, 1)
    uba = ca.vertcat(*rows_ub) if rows_ub else ca.SX(0, 1)
    outputs = [ca.densify(x) for x in (H, g, A, lba, uba, ca.vertcat(*lbx), ca.vertcat(*ubx))]
    function = ca.Function("qp_data", [ctx.q, ctx.u, ctx.p, ctx.dt], outputs,
                           ["q", "u", "p", "dt"], ["H", "g", "A", "lba", "uba", "lbx", "ubx"])
    return AssembledProblem(function, ctx, labels, groups, bound_labels, slack_labels)
