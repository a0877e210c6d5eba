"""A procedure at run time: the IR's monitors and transitions as a :class:`MachineTable`, and what the controller
does each tick before its solve (design of issue 33, "Tick semantics"; docs/runtime.md "The compiled procedure").

**Table.** Every compiled leaf of a monitor or guard (a comparison of a distance, an angle, a norm; a button)
becomes a COMPARE monitor on its compiled value (:mod:`vfdsl.compiler.phases`), ``elapsed`` and ``unchanged``
comparisons the machine's own kinds, ``least_violation`` its status bit, and a flag ``unchanged(INPUT)`` the
condition "unchanged since the last tick" (its ``for`` then counts how long). A named monitor whose expression is
one leaf is that leaf with the monitor's ``for``; any other is a LOGIC program over the monitors it names, after
them (monitors may name monitors later in the file: they are placed in dependency order). A guard is a program.

**A tick** (:meth:`Procedure.tick`), on the checked q, u, the caller's params and dt:

1. at the first tick (and the first after :meth:`Procedure.reset`), every capture takes its start value;
2. raw = monitor_values(q, u, p) with p = [params; captures], and the machine advances (its least-violation
   monitor reads the previous tick's status, 0 at the first);
3. on a transition, the new phase's captures are taken from this tick's q, u, then its funnelled constraints'
   entry errors e_j (beyond their declared tolerances) at this state, captures included; every other's e is 0;
4. ``activity`` = the machine's weights, then 1 for the current phase's hard rows and 0 for every other's, then
   the funnel widths e_j x the machine's funnel factor (1 - t/B over the blend, 0 after it and without one); the
   caller solves the QP with it in this same tick.

Hard rows switch at the transition tick, weights blend, and a hard fixture entered violated by e has the
tolerance declared + e (1 - t/B) during the blend B: it is asked back at the rate e/B instead of at once. A
non-finite e (a NaN from a degenerate capture) gives no funnel: the declared tolerance holds at once.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from vfdsl.compiler.context import ParamLayout
from vfdsl.compiler.phases import MonitorValues, leaf_key, needs_value
from vfdsl.ir import model as ir
from vfdsl.runtime import phase_machine as pm

TIME_OPS = {">": pm.GT, ">=": pm.GE, "<": pm.LT, "<=": pm.LE}
LOGIC_OPS = {"and": pm.AND, "or": pm.OR}


@dataclass(frozen=True)
class PhaseEvent:
    """A transition taken: from phase ``source`` to ``target`` because ``guard`` (as written) held, at ``time`` s
    since the procedure started (the end of the tick's step)."""

    source: str
    target: str
    guard: str
    time: float


class _Translation:
    """IR monitors and guards -> the machine's monitors, programs and watched inputs."""

    def __init__(self, task: ir.Task, values: MonitorValues):
        self.task, self.values = task, values
        self.monitors: list[pm.Monitor] = []
        self.named: dict[str, int] = {}
        self.watched: list[str] = []

    def monitor(self, name: str) -> int:
        if name not in self.named:
            decl = next(m for m in self.task.monitors if m.name == name)
            if isinstance(decl.expr, (ir.Compare, ir.Flag)):
                self.named[name] = self._leaf(decl.expr, decl.hold)
            else:
                self.named[name] = self._add(pm.Monitor(pm.LOGIC, program=tuple(self.program(decl.expr)),
                                                        hold=decl.hold))
        return self.named[name]

    def program(self, node) -> list[int]:
        """The postfix program of a monitor expression."""
        if isinstance(node, ir.MonitorRef):
            return [self.monitor(node.name)]
        if isinstance(node, (ir.Compare, ir.Flag)):
            return [self._leaf(node, 0.0)]
        if isinstance(node, ir.Not):
            return [*self.program(node.items[0]), pm.NOT]
        code = self.program(node.items[0])
        for item in node.items[1:]:
            code += [*self.program(item), LOGIC_OPS[node.expr]]
        return code

    def _leaf(self, node, hold: float) -> int:
        measure = node.measure
        if needs_value(node):
            raw, release = self.values.index[leaf_key(node)]
            return self._add(pm.Monitor(pm.COMPARE, raw=raw, release=release, hold=hold))
        if isinstance(measure, ir.LeastViolation):
            return self._add(pm.Monitor(pm.LEAST_VIOLATION, hold=hold))
        compared = isinstance(node, ir.Compare)
        op, threshold = (TIME_OPS[node.op], node.threshold) if compared else (pm.GT, 0.0)
        if isinstance(measure, ir.Elapsed):
            return self._add(pm.Monitor(pm.ELAPSED, op=op, threshold=threshold, hold=hold))
        if measure.input not in self.watched:
            self.watched.append(measure.input)
        return self._add(pm.Monitor(pm.UNCHANGED, watch=self.watched.index(measure.input), op=op,
                                    threshold=threshold, hold=hold))

    def _add(self, monitor: pm.Monitor) -> int:
        self.monitors.append(monitor)
        return len(self.monitors) - 1


def machine_table(task: ir.Task, values: MonitorValues,
                  input_offsets: dict[str, tuple[int, int]]) -> tuple[pm.MachineTable, dict[str, int]]:
    """The task's machine, and each named monitor's index among its monitors."""
    t = _Translation(task, values)
    for m in task.monitors:
        t.monitor(m.name)
    phases = [p.name for p in task.phases]
    transitions = tuple(pm.Transition(-1 if tr.source is None else phases.index(tr.source), phases.index(tr.target),
                                      tuple(t.program(tr.guard)), tr.blend)
                        for tr in _in_order(task))
    table = pm.MachineTable(initial=next(k for k, p in enumerate(task.phases) if p.initial),
                            final=tuple(p.final for p in task.phases), monitors=tuple(t.monitors),
                            watched=tuple(input_offsets[name] for name in t.watched), transitions=transitions,
                            raw_size=values.size, u_size=sum(size for _, size in input_offsets.values()))
    return table, dict(t.named)


def _in_order(task: ir.Task) -> list[ir.Transition]:
    return sorted(task.transitions, key=lambda tr: tr.order)


class Procedure:
    """The run-time state of a task's procedure: its machine, the full params (the caller's, then the captured
    values) and the activity of the last tick; ``lock`` serialises a controller's ticks (machine, then solve)."""

    def __init__(self, task: ir.Task, layout: ParamLayout, values: MonitorValues, captures,
                 input_offsets: dict[str, tuple[int, int]]):
        self.task = task
        self.table, self._named = machine_table(task, values, input_offsets)
        self._raw = values.function
        self._transitions = _in_order(task)
        self._captures = captures
        self._user = sum(slot.size for slot in layout.slots.values())
        self._defaults = layout.defaults[:self._user]
        self._slots = [[layout.capture_slots[c.name] for c in phase.captures] for phase in task.phases]
        n = self.table.phases
        sizes = [captures.numel_out(n + k) for k in range(n)]
        self._funnels = [slice(sum(sizes[:k]), sum(sizes[:k + 1])) for k in range(n)]    # into entry_error
        self.p = layout.defaults.copy()
        self.activity = np.zeros(2 * n + sum(sizes))
        self.entry_error = np.zeros(sum(sizes))
        """Per funnelled constraint, its error beyond its tolerance when its phase was last entered (0 for every
        phase but the current one's), in its tolerance's unit."""
        self.raw = np.zeros(values.size)
        self.lock = threading.Lock()
        self.reset()

    def reset(self) -> None:
        """Back to the initial phase, its captures retaken at the next tick."""
        self.state = pm.MachineState.initial(self.table)
        self.events: tuple[PhaseEvent, ...] = ()
        self.time = 0.0
        self.entry_error[:] = 0.0
        self._set_activity()

    @property
    def phase(self) -> str:
        return self.task.phases[self.state.phase].name

    @property
    def monitors(self) -> dict[str, bool]:
        """Each named monitor: True when it held at the last tick (False before the first, and when UNKNOWN)."""
        return {name: self.state.value[k] == pm.TRUE for name, k in self._named.items()}

    def tick(self, q: np.ndarray, u: np.ndarray, p: np.ndarray | None, dt: float, last_status: int) -> np.ndarray:
        """The machine's tick before the solve: returns the full params (this tick's, captures included); the
        activity is in :attr:`activity`."""
        self.p[:self._user] = self._defaults if p is None else p
        first = not self.state.started
        if first:
            for k in range(self.table.phases):
                self._capture(k, q, u)
        self.raw[:] = np.asarray(self._raw(q, u, self.p)).ravel()
        source = self.phase
        fired = pm.advance(self.table, self.state, self.raw, u, dt, 0 if first else last_status)
        self.time += dt
        self.events = ()
        if fired >= 0:
            self._capture(self.state.phase, q, u)
            self._measure_entry(self.state.phase, q, u)
            transition = self._transitions[fired]
            self.events = (PhaseEvent(source, self.phase, transition.text, self.time),)
        self._set_activity()
        return self.p

    def _capture(self, phase: int, q, u) -> None:
        values = np.asarray(self._captures.call([q, u, self.p])[phase]).ravel()
        offset = 0
        for slot in self._slots[phase]:
            self.p[slot.offset:slot.offset + slot.size] = values[offset:offset + slot.size]
            offset += slot.size

    def _measure_entry(self, phase: int, q, u) -> None:
        """The entered phase's funnelled constraints' errors at this state (its captures taken); 0 elsewhere and
        for an error that is not a finite number."""
        n = self.table.phases
        e = np.asarray(self._captures.call([q, u, self.p])[n + phase], dtype=float).ravel()
        self.entry_error[:] = 0.0
        self.entry_error[self._funnels[phase]] = np.where(np.isfinite(e) & (e > 0), e, 0.0)

    def _set_activity(self) -> None:
        n = self.table.phases
        self.activity[:n] = self.state.weight
        self.activity[n:2 * n] = 0.0
        self.activity[n + self.state.phase] = 1.0
        self.activity[2 * n:] = self.entry_error * self.state.funnel
