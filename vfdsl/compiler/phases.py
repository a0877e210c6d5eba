"""A procedure's phases in the one QP, its captures and its monitors' compiled values (design of issue 33).

**Activity.** The QP data of a task with P phases take one more argument, ``activity`` (2P numbers,
:data:`vfdsl.codegen.tick_buffers.PHASE_ARGUMENTS`): a_k in [0, 1], phase k's weight, then h_k in {0, 1}, its hard
rows on. Phase k's statements are gated (:class:`Gate`): an objective term's weight w becomes a_k w, a soft
constraint's slack weight too (and each target is scaled by its level's coverage, the summed a_k of the phases
with terms on the level: :func:`vfdsl.compiler.assemble._coverage`); a hard row's bounds become (lb, ub) where
h_k > 1/2, else (-inf, +inf) (DAQP treats an infinite bound as inactive, and the violation output and the
least-violation phase count such a row as met).
The task's phase-less statements are not gated: a task without phases compiles to the same graph as before
procedures. Values, not structure: a transition changes no sparsity. (The step solves, per phase, only the rows
that phase can hold: :mod:`vfdsl.compiler.cases`.)

**Funnel.** After the 2P entries, ``activity`` holds one width w_j >= 0 per funnelled constraint (a phase's hard
constraint whose primitive has a tolerance, :func:`funnelled`, in phase order): its rows' bounds become
(lb - w_j k_lb, ub + w_j k_ub), k = -d lb/d eps and d ub/d eps the rows' scale in the tolerance eps, read off the
lowering with eps a symbol (1 for the facet rows of stays_at, along, keeps_direction, ...; 0 for a row the
tolerance does not enter, such as on_plane's "not below"), so a width in the tolerance's unit widens the
tolerance by exactly that: eps + w_j. Its entry error e_j, the width that makes its rows hold at dq = 0
(max over rows with k > 0 of lb/k_lb and -ub/k_ub, and 0), is an output of ``captures`` (below); the run time
sets w_j = e_j x the machine's funnel factor (:mod:`vfdsl.runtime.procedure`).

**Captures** are run-time param slots after the params (:class:`vfdsl.compiler.context.ParamLayout`): a
:class:`~vfdsl.ir.model.CaptureRef` reads its slot as a param of its type. ``captures(q, u, p)`` gives, per phase,
its captures' values at this tick's state (a frame's origin, tool axis or pose [origin; roll, pitch, yaw] in the
world, an input, a param), in slot order, which the run time writes into p when the phase is entered; then, per
phase, its funnelled constraints' entry errors e_j at (q, u, p), which the run time reads with p holding the
captures just taken.

**Monitors.** ``monitor_values(q, u, p) -> raw`` gives each compiled comparison's signed margin (true when > 0):
``m < t`` gives t - m, ``m > t`` gives m - t (at equality false: 0 is not > 0); ``m <= t`` and ``m >= t`` give the
same margin raised to the smallest positive double where it is 0 (:func:`_inclusive`), so that they hold at equality, as
``vfdsl check`` reads them (``norm(hand) <= 0 N`` with the hands exactly off, ``distance(tip, p) >= 0 mm`` at p);
``release r`` adds a second value, r - m for ``<`` (m - r for ``>``), which switches the latch off when
<= 0 (:mod:`vfdsl.runtime.phase_machine`); a button gives u - 1/2 (pressed above one half). The measures:
``distance`` to a point |x - c|, to a line |(I - d d')(x - c)|, to a plane n'(x - c) (signed); ``angle`` between
the tool axis a and a direction d, atan2(|a x d|, a'd) in [0, pi]; ``norm`` of an input or its part.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from vfdsl.compiler import registry
from vfdsl.compiler.context import Context
from vfdsl.compiler.geometry import rpy_of
from vfdsl.compiler.rows import Rows
from vfdsl.inputs import input_type
from vfdsl.ir import model as ir

INF = ca.inf


@dataclass(frozen=True)
class Gate:
    """How a statement is switched: ``weight`` multiplies its objective weights (None: 1), ``on`` (> 1/2) keeps its
    hard rows' bounds (None: always); ``phase``: its phase's name (None: every phase); ``width``: a funnelled
    constraint's funnel width (None: not funnelled)."""

    weight: ca.SX | None = None
    on: ca.SX | None = None
    phase: str | None = None
    width: ca.SX | None = None

    def scaled(self, weight):
        """An objective or slack weight as this gate scales it."""
        return weight if self.weight is None else weight * self.weight

    def bounds(self, lb, ub):
        """A hard row's (or a joint bound's) bounds: as given while on, else (-inf, +inf)."""
        if self.on is None:
            return lb, ub
        on = self.on > 0.5
        return ca.if_else(on, lb, -INF), ca.if_else(on, ub, INF)


ALWAYS = Gate()


def funnels(c: ir.Constraint) -> bool:
    """Whether a phase's constraint gets a funnel width: hard, of a primitive with a tolerance."""
    return not c.soft and c.tolerance is not None


def funnelled(phase: ir.Phase) -> list[ir.Constraint]:
    """The phase's constraints that get a funnel width, in statement order."""
    return [c for c in phase.constraints if funnels(c)]


def gated_statements(task: ir.Task, ctx: Context) -> tuple[list[tuple[ir.Constraint, Gate]],
                                                          list[tuple[ir.Objective, Gate]]]:
    """Every constraint and objective of the task with its gate: the phase-less ones first (ungated), then each
    phase's, in phase order, gated by its activity entries (a funnelled constraint's gate with its width, the
    widths appended to ``ctx.activity``)."""
    constraints = [(c, ALWAYS) for c in task.constraints]
    objectives = [(o, ALWAYS) for o in task.objectives]
    n = len(task.phases)
    if n and ctx.activity.numel() == 2 * n:
        widths = sum(len(funnelled(phase)) for phase in task.phases)
        ctx.activity = ca.vertcat(ctx.activity, ca.SX.sym("funnel", widths))
    j = 2 * n
    for k, phase in enumerate(task.phases):
        gate = Gate(ctx.activity[k], ctx.activity[n + k], phase.name)
        for c in phase.constraints:
            if funnels(c):
                constraints.append((c, replace(gate, width=ctx.activity[j])))
                j += 1
            else:
                constraints.append((c, gate))
        objectives += [(o, gate) for o in phase.objectives]
    return constraints, objectives


def lowered(c: ir.Constraint, gate: Gate, ctx: Context) -> Rows:
    """The constraint's rows; a funnelled one's with its bounds widened by its width: (lb - w k_lb, ub + w k_ub)."""
    if gate.width is None:
        return registry.constraint(c.primitive).lower(c, ctx)
    rows, k_lb, k_ub = _scaled_rows(c, ctx)
    return replace(rows, lb=rows.lb - gate.width * k_lb, ub=rows.ub + gate.width * k_ub)


def _scaled_rows(c: ir.Constraint, ctx: Context) -> tuple[Rows, ca.DM, ca.DM]:
    """The rows at the declared tolerance eps and their scales k_lb = -d lb/d eps, k_ub = d ub/d eps, from the
    lowering with eps a symbol (the rows are affine in eps; a scale that depends on the state is an error)."""
    eps = ca.SX.sym("eps")
    rows = registry.constraint(c.primitive).lower(c.model_copy(update={"tolerance": eps}), ctx)
    lb, ub = ca.SX(rows.lb), ca.SX(rows.ub)
    k_lb, k_ub = (ca.evalf(ca.substitute(k, eps, c.tolerance))
                  for k in (-ca.jacobian(lb, eps), ca.jacobian(ub, eps)))
    return (replace(rows, lb=ca.substitute(lb, eps, c.tolerance), ub=ca.substitute(ub, eps, c.tolerance)),
            k_lb, k_ub)


def _entry_error(c: ir.Constraint, ctx: Context) -> ca.SX:
    """e >= 0, how far beyond its declared tolerance the constraint is at this state, in the tolerance's unit: the
    least width that makes its rows hold at dq = 0."""
    rows, k_lb, k_ub = _scaled_rows(c, ctx)
    k_lb, k_ub = np.array(k_lb).ravel(), np.array(k_ub).ravel()
    excess = [rows.lb[i] / k_lb[i] for i in np.flatnonzero(k_lb > 0)]
    excess += [-rows.ub[i] / k_ub[i] for i in np.flatnonzero(k_ub > 0)]
    return ca.fmax(0, ca.mmax(ca.vertcat(*excess))) if excess else ca.SX(0)


def captures_function(task: ir.Task, ctx: Context) -> ca.Function:
    """``captures(q, u, p) -> (values of phase 1, ..., values of phase P, errors of phase 1, ..., of phase P)``:
    each phase's captures, in slot order, then its funnelled constraints' entry errors (:func:`funnelled`)."""
    outputs, errors = [], []
    for phase in task.phases:
        values = [_capture_value(c.source, ctx) for c in phase.captures]
        outputs.append(ca.vertcat(*values) if values else ca.SX(0, 1))
        entry = [_entry_error(c, ctx) for c in funnelled(phase)]
        errors.append(ca.vertcat(*entry) if entry else ca.SX(0, 1))
    return ca.Function("captures", [ctx.q, ctx.u, ctx.p], outputs + errors, ["q", "u", "p"],
                       [phase.name for phase in task.phases] + [f"{phase.name} funnel" for phase in task.phases])


def _capture_value(source, ctx: Context) -> ca.SX:
    if isinstance(source, ir.FrameMeasure):
        frame = ctx.frame(source.frame)
        return {"position": lambda: frame.p, "axis": lambda: frame.axis,
                "pose": lambda: ca.vertcat(frame.p, rpy_of(frame.R))}[source.part]()
    if isinstance(source, ir.InputRef):
        return ctx.input(source)
    slot = ctx.layout.slots[source.name]
    return ctx.p[slot.offset:slot.offset + slot.size]


def needs_value(node) -> bool:
    """Whether a monitor expression's leaf (a Compare or a Flag) is a compiled value; else the phase machine
    measures it (elapsed, unchanged, least_violation)."""
    return isinstance(node.measure, (ir.Distance, ir.Angle, ir.Norm, ir.Button))


def leaf_key(node) -> str:
    """The key of a monitor expression's leaf in :class:`MonitorValues`.index."""
    return node.model_dump_json()


@dataclass(frozen=True)
class MonitorValues:
    """``function``: (q, u, p) -> raw, the compiled values; ``index``: per leaf (:func:`leaf_key`) its value's
    index in raw and its release value's (-1: none)."""

    function: ca.Function
    index: dict[str, tuple[int, int]]

    @property
    def size(self) -> int:
        return self.function.numel_out(0)


def monitor_values(task: ir.Task, ctx: Context) -> MonitorValues:
    """Every compiled leaf of the task's monitors and transition guards, each once."""
    raw: list[ca.SX] = []
    index: dict[str, tuple[int, int]] = {}

    expressions = [*(monitor.expr for monitor in task.monitors), *(t.guard for t in task.transitions)]
    for node in (leaf for expr in expressions for leaf in ir.expression_leaves(expr)):
        if not (isinstance(node, (ir.Compare, ir.Flag)) and needs_value(node)) or leaf_key(node) in index:
            continue
        measure = _measure(node.measure, ctx)
        if isinstance(node, ir.Flag):
            margins = [measure - 0.5]
        else:
            sign = 1 if node.op in ("<", "<=") else -1
            margin = sign * (node.threshold - measure)
            margins = [_inclusive(margin) if node.op in ("<=", ">=") else margin]
            if node.release is not None:
                margins.append(sign * (node.release - measure))
        index[leaf_key(node)] = (len(raw), len(raw) + 1 if len(margins) > 1 else -1)
        raw.extend(margins)
    values = ca.vertcat(*raw) if raw else ca.SX(0, 1)
    return MonitorValues(ca.Function("monitor_values", [ctx.q, ctx.u, ctx.p], [values], ["q", "u", "p"], ["raw"]),
                         index)


def _inclusive(margin: ca.SX) -> ca.SX:
    """A non-strict comparison's margin, true (> 0) where the margin is >= 0: 0 becomes the smallest positive
    double; NaN stays NaN (unknown)."""
    return ca.if_else(margin >= 0, ca.fmax(margin, np.finfo(float).tiny), margin)


def _measure(measure, ctx: Context) -> ca.SX:
    if isinstance(measure, ir.Distance):
        x = ctx.frame(measure.frame).p
        kind = ctx.kind(measure.to)
        if kind == "line":
            line = ctx.line(measure.to)
            d = x - line.point
            return ca.norm_2(d - line.direction * (line.direction.T @ d))
        if kind == "plane":
            plane = ctx.plane(measure.to)
            return plane.normal.T @ (x - plane.point)
        return ca.norm_2(x - ctx.point(measure.to))
    if isinstance(measure, ir.Angle):
        a, d = ctx.frame(measure.frame).axis, ctx.direction(measure.direction)
        return ca.atan2(ca.norm_2(ca.cross(a, d)), a.T @ d)
    u = ctx.input(ir.InputRef(name=measure.input))
    if isinstance(measure, ir.Button):
        return u[0]
    if measure.part == "all":
        return ca.norm_2(u)
    start = 3 if measure.part == "angular" and input_type(ctx.task.input(measure.input).type).linear else 0
    return ca.norm_2(u[start:start + 3])
