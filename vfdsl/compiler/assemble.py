"""Assembly: a checked task -> one CasADi Function giving the QP of a control tick.

    qp_data(q, u, p, dt) -> (H, g, A, lba, uba, lbx, ubx, R1, r1, ..., Rk, rk)

is the QP in CasADi conic's standard form over x = [dq; s] (s: one slack per soft constraint):

    minimize 1/2 x' H x + g' x   subject to   lba <= A x <= uba,   lbx <= x <= ubx

- objective: every term is a rate error w || E dq/dt - f ||^2 (:class:`~vfdsl.compiler.rows.Term`); multiplied by
  dt^2 (which changes no minimizer) it is w || E dq - f dt ||^2, per tick. A soft constraint's slack s (row units
  per tick) costs w s^2 = w dt^2 (s/dt)^2, a rate too. H = 2 sum_k w_k E_k' E_k + rho I (a tiny floor that keeps
  H positive definite when the terms leave some motion free), g = -2 sum_k w_k E_k' f_k dt;
- priority levels: terms are grouped by (priority, after) in increasing order; level j's own cost is
  1/2 || Rj x - rj ||^2 (its terms only: Rj stacks their rows sqrt(2 w) E, rj their targets sqrt(2 w) f dt),
  which the solver minimizes while it keeps every level above at its optimum (:mod:`vfdsl.runtime.qp`), and a
  reader can say how far each term got. H, g are the sum over all levels (the least-violation phase uses them,
  H with the floor). With a single level, only H and
  g are given. Every level is given, a last level of `damping` alone too: it picks the smallest motion among
  the optimal ones of the levels above, which no other level may do in their place (a damping folded into a
  tracked level would trade tracking for it);
- hard rows that bound one joint each (joint limits, joint speeds) become the variable bounds lbx, ubx
  (their intersection); every other hard row is a row of A;
- a soft constraint's rows get its slack: A dq + s >= c lb (and A dq - s <= c ub for two-sided rows), s >= 0.
  c = min(1, k dt), k = SOFT_RESTORE_RATE, restores a position-like constraint at the rate k rather than in one
  tick, which makes the slack a rate and the penetration under a steady push independent of dt:
  w_t v / (w k) for a push asking v m/s through a track term of weight w_t (docs/language.md, weights).
  Rate constraints (speeds) keep c = 1.

Every row of A and every variable bound keeps a :class:`RowLabel` naming its primitive, frame, facet and
source line (and the fixture ``use`` sites it came through), and its phase in a procedure.

A procedure's phases are all in this one QP, switched by the ``activity`` argument (:mod:`vfdsl.compiler.phases`):
``qp_data(q, u, p, dt, activity)``, which also carries the funnel widths of the phases' hard constraints; the
step solves each phase's part of it (:mod:`vfdsl.compiler.cases`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from vfdsl.codegen import tick_buffers
from vfdsl.compiler import registry
from vfdsl.compiler.context import Context
from vfdsl.compiler.phases import Gate, gated_statements, lowered
from vfdsl.compiler.rows import Rows
from vfdsl.errors import Span
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot

HESSIAN_FLOOR = 1e-9
SOFT_RESTORE_RATE = 10.0
"""k (1/s): a violated soft constraint of a position-like quantity is asked back at rate k (time constant 0.1 s)."""


@dataclass(frozen=True)
class RowLabel:
    """Where a row of the QP comes from."""

    primitive: str
    frame: str | None
    facet: str
    span: Span
    via: tuple[Span, ...] = ()
    soft: bool = False
    phase: str | None = None         # a procedure's phase (None: held in every phase)

    def __str__(self) -> str:
        return self.text(facet=True)

    def text(self, facet: bool = True) -> str:
        """``soft stays_at(tip) facet 3/6 in phase p [file:line via ...]``; without ``facet``, the constraint alone."""
        on = f"({self.frame})" if self.frame else ""
        kind = "soft " if self.soft else ""
        where = f"{self.span.file}:{self.span.line}"
        through = "".join(f" via {s.file}:{s.line}" for s in self.via)
        phase = f" in phase {self.phase}" if self.phase else ""
        return f"{kind}{self.primitive}{on}{' ' + self.facet if facet else ''}{phase} [{where}{through}]"


@dataclass
class AssembledProblem:
    """The tick's QP as a CasADi Function, with the layout of its inputs and the labels of its rows."""

    function: ca.Function
    context: Context
    row_labels: list[RowLabel]
    row_groups: list[int]                    # per row of A, the index of the constraint it comes from
    bound_labels: list[list[RowLabel]]       # per variable, the hard bounds that shaped it (may be empty)
    slack_labels: list[RowLabel] = field(default_factory=list)
    levels: list[list[str]] = field(default_factory=list)   # per priority level, what it solves ("track(tip) linear")

    @property
    def nq(self) -> int:
        return self.context.nq

    @property
    def n_slack(self) -> int:
        return len(self.slack_labels)

    @property
    def last_level_is_damping(self) -> bool:
        """The task has priority levels and its last one is `damping` alone (positive definite on dq: the solver
        may make it its own cost, :func:`vfdsl.runtime.qp.build_step_function`)."""
        return len(self.levels) > 1 and all(name.startswith("damping(") for name in self.levels[-1])


def urdf_speed_limits(task: ir.Task, robot: Robot) -> np.ndarray | None:
    """The joint speeds (rad/s or m/s) every tick is held to when ``task`` states no hard ``joint_speed()`` outside
    its phases: the URDF's velocity limits, +inf for a joint without a positive, finite one; None when the task
    states its own (its rows replace them). Its rows are linearized, right only for small motions, and a step
    beyond what the joints can do in one tick is not a motion the robot can make (without it a tool placed 1 m
    from lecture_stay_near_goal's goal got a 1.25 rad joint step, reported OPTIMAL, that took the tip 145 mm
    further away)."""
    if any(c.primitive == "joint_speed" and not c.soft for c in task.constraints):
        return None
    limits = np.asarray(robot.velocity_limit, dtype=float)
    return np.where(np.isfinite(limits) & (limits > 0), limits, np.inf)


def _velocity_limits(task: ir.Task, ctx: Context, lbx: list, ubx: list, labels: list[list[RowLabel]]) -> None:
    """|dq_i| <= qdot_max_i dt for the joints :func:`urdf_speed_limits` bounds."""
    robot = ctx.robot
    limits = urdf_speed_limits(task, robot)
    if limits is None:
        return
    for i, limit in enumerate(limits):
        if np.isfinite(limit):
            lbx[i] = ca.fmax(lbx[i], -limit * ctx.dt)
            ubx[i] = ca.fmin(ubx[i], limit * ctx.dt)
            labels[i].append(RowLabel("joint_speed", None, f"{robot.joint_names[i]} (the URDF's velocity limit)",
                                      task.robots[0].span))


def _label(c: ir.Constraint, facet: str, gate: Gate) -> RowLabel:
    return RowLabel(c.primitive, c.frame, facet, c.span, tuple(c.via), c.soft, gate.phase)


@dataclass
class _Level:
    """One priority level's cost sum_k w_k || E_k x - f_k dt ||^2 = 1/2 || R x - r ||^2 + const, with the rows
    R_k = sqrt(2 w_k) E_k and targets r_k = sqrt(2 w_k) f_k dt; as H = R'R, g = -R'r (without the Hessian floor)."""

    H: ca.SX
    g: ca.SX
    R: list
    r: list
    names: list[str]                 # what it solves, for labels ("track(tip) linear")
    terms: set[str]                  # the objective terms it holds ("track", "damping", ...; "soft")


def _objective_levels(objectives: list[tuple[ir.Objective, Gate]], ctx: Context,
                      soft: list[tuple[ir.Constraint, Gate]], n: int) -> list[_Level]:
    """Each priority level's cost over x = [dq; s] (n entries), levels in the order they are solved; each weight
    as its statement's gate scales it, each target by its level's coverage (:func:`_coverage`)."""
    terms = []                                            # (level, gate, weight, E, f dt, name, term)
    for objective, gate in objectives:
        for term in registry.objective(objective.term).lower(objective, ctx):
            E = ca.horzcat(term.E, ca.SX.zeros(term.E.shape[0], n - ctx.nq))
            name = f"{objective.term}{_frame_of(objective)}{' ' + term.part if term.part else ''}"
            terms.append(((objective.priority, term.after), gate, objective.weight, E, term.f * ctx.dt, name,
                          objective.term))
    for index, (c, gate) in enumerate(soft):
        E = ca.SX(1, n)
        E[ctx.nq + index] = 1
        terms.append(((c.priority, 0), gate, c.weight, E, ca.SX.zeros(1),
                      f"soft {c.primitive}({c.frame or ''}) slack", "soft"))
    coverage = _coverage([(key, gate) for key, gate, *_ in terms])
    levels: dict[tuple[int, int], _Level] = {}
    for key, gate, weight, E, f, name, term in terms:
        level = levels.setdefault(key, _Level(ca.SX.zeros(n, n), ca.SX.zeros(n), [], [], [], set()))
        w = gate.scaled(weight)
        R, r = ca.sqrt(2 * w) * E, ca.sqrt(2 * w) * coverage[key] * f
        level.H += R.T @ R
        level.g -= R.T @ r
        level.R.append(R)
        level.r.append(r)
        level.names.append(name)
        level.terms.add(term)
    return [levels[key] for key in sorted(levels)]


def _coverage(placed: list[tuple[tuple[int, int], Gate]]) -> dict[tuple[int, int], ca.SX]:
    """c_L per level L: 1 where a statement outside the phases has a term on L, else the summed activity of the
    phases with terms on L (at most 1). Every target on L is scaled by c_L: in a steady phase c_L is 1 wherever
    the phase has terms; during a blend from a phase with terms on L to one without (a clutch phase with only
    damping), c_L = 1 - s and the old terms' motion ramps down with their weights instead of running in full
    until s = 1 (a weight alone on its level sets no trade-off, only the target does); into such a level it ramps
    up from 0. Where both phases have terms on L, c_L = 1 and the weights alone blend."""
    phases: dict[tuple[int, int], dict[str, ca.SX]] = {}
    outside: set[tuple[int, int]] = set()
    for key, gate in placed:
        if gate.weight is None:
            outside.add(key)
        else:
            phases.setdefault(key, {})[gate.phase] = gate.weight
    coverage = {key: ca.SX(1) for key in outside}
    for key, activity in phases.items():
        if key not in outside:
            coverage[key] = ca.fmin(1, sum(activity.values(), ca.SX(0)))
    return coverage


def _frame_of(objective: ir.Objective) -> str:
    frame = objective.args.get("frame")
    return f"({frame.name})" if isinstance(frame, ir.FrameRef) else "()"


QP_OUTPUTS = ("H", "g", "A", "lba", "uba", "lbx", "ubx")
"""qp_data's first outputs; the priority levels' (R_j, r_j) pairs follow (:func:`output_names`)."""


def output_names(levels: int) -> list[str]:
    """qp_data's output names with ``levels`` priority levels (one level, or none: no R_j, r_j)."""
    pairs = range(1, levels + 1) if levels > 1 else ()
    return [*QP_OUTPUTS, *(f"{part}{j}" for j in pairs for part in ("R", "r"))]


def assemble(task: ir.Task, robot: Robot) -> AssembledProblem:
    ctx = Context(task, robot)
    nq = ctx.nq
    inf = ca.DM.inf(1)

    lbx, ubx = [-inf] * nq, [inf] * nq
    bound_labels: list[list[RowLabel]] = [[] for _ in range(nq)]
    rows_A, rows_lb, rows_ub, labels, groups = [], [], [], [], []
    soft_rows: list[tuple[int, Rows, ir.Constraint, int, Gate]] = []
    constraints, objectives = gated_statements(task, ctx)
    for number, (c, gate) in enumerate(constraints):
        rows = lowered(c, gate, ctx)
        if c.soft:
            soft_rows.append((len(soft_rows), rows, c, number, gate))
        elif rows.bounds:
            for i in range(nq):
                lb, ub = gate.bounds(rows.lb[i], rows.ub[i])
                lbx[i] = ca.fmax(lbx[i], lb)
                ubx[i] = ca.fmin(ubx[i], ub)
                bound_labels[i].append(_label(c, rows.facets[i], gate))
        else:
            lb, ub = gate.bounds(rows.lb, rows.ub)
            rows_A.append(rows.A)
            rows_lb.append(lb)
            rows_ub.append(ub)
            labels += [_label(c, f, gate) for f in rows.facets]
            groups += [number] * len(rows.facets)

    _velocity_limits(task, ctx, lbx, ubx, bound_labels)

    # soft constraints: one slack each, appended after dq
    n_slack = len(soft_rows)
    A_full = [ca.horzcat(A, ca.SX.zeros(A.shape[0], n_slack)) for A in rows_A]
    slack_labels = []
    for index, rows, c, number, gate in soft_rows:
        column = ca.DM.zeros(1, n_slack)
        column[index] = 1
        k = rows.A.shape[0]
        one_sided = rows.ub.is_constant() and bool(np.all(np.isinf(np.array(ca.DM(rows.ub)))))
        restore = 1 if registry.constraint(c.primitive).spec.rate else ca.fmin(1, SOFT_RESTORE_RATE * ctx.dt)
        A_full.append(ca.horzcat(rows.A, ca.repmat(column, k, 1)))
        rows_lb.append(restore * rows.lb)
        rows_ub.append(ca.DM.inf(k))
        labels += [_label(c, f + " (lower)" if not one_sided else f, gate) for f in rows.facets]
        groups += [number] * k
        if not one_sided:
            A_full.append(ca.horzcat(rows.A, ca.repmat(-column, k, 1)))
            rows_lb.append(-ca.DM.inf(k))
            rows_ub.append(restore * rows.ub)
            labels += [_label(c, f + " (upper)", gate) for f in rows.facets]
            groups += [number] * k
        slack_labels.append(_label(c, "slack", gate))
    lbx += [ca.DM(0.0)] * n_slack
    ubx += [inf] * n_slack

    A = ca.vertcat(*A_full) if A_full else ca.SX(0, nq + n_slack)
    lba = ca.vertcat(*rows_lb) if rows_lb else ca.SX(0, 1)
    uba = ca.vertcat(*rows_ub) if rows_ub else ca.SX(0, 1)
    levels = _objective_levels(objectives, ctx, [(c, gate) for _, _, c, _, gate in soft_rows], nq + n_slack)
    floor = HESSIAN_FLOOR * ca.SX.eye(nq + n_slack)
    H = floor + sum((level.H for level in levels), ca.SX.zeros(nq + n_slack, nq + n_slack))
    g = sum((level.g for level in levels), ca.SX.zeros(nq + n_slack))
    outputs = [H, g, A, lba, uba, ca.vertcat(*lbx), ca.vertcat(*ubx)]
    if len(levels) > 1:
        for level in levels:
            outputs += [ca.vertcat(*level.R), ca.vertcat(*level.r)]
    names = output_names(len(levels))
    arguments = tick_buffers.data_arguments(bool(task.phases))
    function = ca.Function("qp_data", [getattr(ctx, name) for name in arguments],
                           [ca.densify(x) for x in outputs], list(arguments), names)
    return AssembledProblem(function, ctx, labels, groups, bound_labels, slack_labels,
                            [level.names for level in levels])
