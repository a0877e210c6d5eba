"""A procedure's phases in the one QP, its captures and its monitors' compiled values (design of issue 33).

**Activity.** The QP data of a task with P phases take one more argument, ``activity`` (2P numbers,
:data:`vfdsl.codegen.tick_buffers.PHASE_ARGUMENTS`): a_k in [0, 1], phase k's weight, then h_k in {0, 1}, its hard
rows on. Phase k's statements are gated (:class:`Gate`): an objective term's weight w becomes a_k w, a soft
constraint's slack weight too; a hard row's bounds become (lb, ub) where h_k > 1/2, else (-inf, +inf) (DAQP treats
an infinite bound as inactive, and the violation output and the least-violation phase count such a row as met).
The task's phase-less statements are not gated: a task without phases compiles to the same graph as before
procedures. Values, not structure: a transition changes no sparsity, so the solver's warm start survives it.

**Captures** are run-time param slots after the params (:class:`vfdsl.compiler.context.ParamLayout`): a
:class:`~vfdsl.ir.model.CaptureRef` reads its slot as a param of its type. ``captures(q, u, p)`` gives, per phase,
its captures' values at this tick's state (a frame's origin or tool axis in the world, an input, a param), in slot
order, which the run time writes into p when the phase is entered.

**Monitors.** ``monitor_values(q, u, p) -> raw`` gives each compiled comparison's signed margin (true when > 0):
``m < t`` and ``m <= t`` give t - m, ``m > t`` and ``m >= t`` give m - t (at equality both are false: 0 is not
> 0); ``release r`` adds a second value, r - m for ``<`` (m - r for ``>``), which switches the latch off when
<= 0 (:mod:`vfdsl.runtime.phase_machine`); a button gives u - 1/2 (pressed above one half). The measures:
``distance`` to a point |x - c|, to a line |(I - d d')(x - c)|, to a plane n'(x - c) (signed); ``angle`` between
the tool axis a and a direction d, atan2(|a x d|, a'd) in [0, pi]; ``norm`` of an input or its part.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from vfdsl.compiler.context import Context
from vfdsl.inputs import input_type
from vfdsl.ir import model as ir

INF = ca.inf


@dataclass(frozen=True)
class Gate:
    """How a statement is switched: ``weight`` multiplies its objective weights (None: 1), ``on`` (> 1/2) keeps its
    hard rows' bounds (None: always); ``phase``: its phase's name (None: every phase)."""

    weight: ca.SX | None = None
    on: ca.SX | None = None
    phase: str | None = None

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


def gated_statements(task: ir.Task, ctx: Context) -> tuple[list[tuple[ir.Constraint, Gate]],
                                                          list[tuple[ir.Objective, Gate]]]:
    """Every constraint and objective of the task with its gate: the phase-less ones first (ungated), then each
    phase's, in phase order, gated by its activity entries."""
    constraints = [(c, ALWAYS) for c in task.constraints]
    objectives = [(o, ALWAYS) for o in task.objectives]
    n = len(task.phases)
    for k, phase in enumerate(task.phases):
        gate = Gate(ctx.activity[k], ctx.activity[n + k], phase.name)
        constraints += [(c, gate) for c in phase.constraints]
        objectives += [(o, gate) for o in phase.objectives]
    return constraints, objectives


def captures_function(task: ir.Task, ctx: Context) -> ca.Function:
    """``captures(q, u, p) -> (values of phase 1, ..., values of phase P)``: each phase's captures, in slot order."""
    outputs = []
    for phase in task.phases:
        values = [_capture_value(c.source, ctx) for c in phase.captures]
        outputs.append(ca.vertcat(*values) if values else ca.SX(0, 1))
    return ca.Function("captures", [ctx.q, ctx.u, ctx.p], outputs, ["q", "u", "p"],
                       [phase.name for phase in task.phases])


def _capture_value(source, ctx: Context) -> ca.SX:
    if isinstance(source, ir.FrameMeasure):
        frame = ctx.frame(source.frame)
        return frame.p if source.part == "position" else frame.axis
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

    def visit(node) -> None:
        if isinstance(node, (ir.And, ir.Or, ir.Not)):
            for item in node.items:
                visit(item)
        elif isinstance(node, (ir.Compare, ir.Flag)) and needs_value(node) and leaf_key(node) not in index:
            measure = _measure(node.measure, ctx)
            if isinstance(node, ir.Flag):
                margins = [measure - 0.5]
            else:
                sign = 1 if node.op in ("<", "<=") else -1
                margins = [sign * (node.threshold - measure)]
                if node.release is not None:
                    margins.append(sign * (node.release - measure))
            index[leaf_key(node)] = (len(raw), len(raw) + 1 if len(margins) > 1 else -1)
            raw.extend(margins)

    for monitor in task.monitors:
        visit(monitor.expr)
    for transition in task.transitions:
        visit(transition.guard)
    values = ca.vertcat(*raw) if raw else ca.SX(0, 1)
    return MonitorValues(ca.Function("monitor_values", [ctx.q, ctx.u, ctx.p], [values], ["q", "u", "p"], ["raw"]),
                         index)


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
