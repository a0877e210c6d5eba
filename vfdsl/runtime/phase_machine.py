"""The discrete part of a procedure's tick: monitors, the phase and its transitions, blend weights and the funnel.

A pure function of a fixed table and a small state, run once per tick before the solve (design of issue 33,
"Tick semantics"); the generated tick runs its C twin, ``vfdsl/codegen/phase_machine.h``, with the same steps in
the same order, so both give the same phases, transitions and weights to the last bit (the C is compiled with
``-ffp-contract=off``, every operation here is one IEEE double operation).

**Inputs of a tick.** ``raw``: the tick's compiled comparison values, from this tick's q and inputs (``a < t``
compiles to t - a, ``a > t`` to a - t: true when > 0; ``a <= t`` and ``a >= t`` to the same, but > 0 at equality too,
:func:`vfdsl.compiler.phases._inclusive`; a ``release r`` compiles a second value, r - a for ``<``,
that must go <= 0 to switch the monitor off); ``u``: the inputs; ``dt``: the tick's period (a value that is not
a finite number >= 0 counts as 0); ``last_status``: the previous tick's StepStatus bits.

**Truth values.** A monitor is TRUE, FALSE or UNKNOWN. A NaN compiled value is UNKNOWN (a NaN comparison is
neither true nor false), and so is ``unchanged`` of an input holding a NaN; ``not``, ``and``, ``or`` follow
Kleene's logic (``not`` UNKNOWN is UNKNOWN, FALSE ``and`` UNKNOWN is FALSE, TRUE ``or`` UNKNOWN is TRUE). A
guard fires only when TRUE, so a NaN never fires a transition, even under ``not``.

**Times at tick resolution.** A time t (a held time, ``elapsed``, ``unchanged``, the blend's) is compared with a
duration T as if both were counted in ticks: t equals T when |t - T| <= dt/2, so t >= T is t >= T - dt/2, t > T
is t > T + dt/2, t <= T is t <= T + dt/2, t < T is t < T - dt/2 (dt = 0: exact). Times accumulate the dt given,
and summing 1 ms fifty times rounds to either side of 50 ms; at tick resolution a duration of k ticks is reached
at the k-th tick whatever the rounding.

**One tick**, :func:`advance`:

1. The first tick enters the initial phase (``elapsed`` 0); every later one adds dt to ``elapsed``.
2. Each watched input: ``unchanged`` += dt when every component equals the last tick's, else 0 (the first tick,
   and any tick with a NaN, count as a change); the last value is kept.
3. Monitors in table order (a monitor names only earlier ones): the condition is a compiled comparison (with
   ``release``: a latch, off until the value is > 0, then on until the release value is <= 0; an UNKNOWN value
   leaves the latch as it was), an ``elapsed`` or ``unchanged`` comparison, the least-violation bit of
   ``last_status``, or a program over earlier monitors. Its held time is the sum of dt over the consecutive
   ticks, this one included, where the condition is TRUE (0 otherwise): a condition TRUE from tick 1 on has held
   k dt at tick k. The monitor is TRUE when the condition is TRUE and the held time reaches its ``hold``
   (``for``): a ``for 50 ms`` at dt 1 ms is TRUE from the 50th tick over the limit on; otherwise FALSE, or
   UNKNOWN when the condition is. Held timers and latches are the task's: a transition keeps them.
4. At most one transition: out of a non-final phase, the first in table (file) order whose source is the
   current phase, or any (-1) with another phase as its target (``* -> B`` never fires in B), and whose guard
   is TRUE. Two guards TRUE together: the first fires; the other is
   evaluated again next tick, from the new phase. A guard TRUE at the first tick fires at the first tick (the
   initial phase is entered and left in it; its blend starts from the initial phase's full weight).
5. On a transition (also into the current phase: a self-transition restarts the phase): ``elapsed`` = 0, the
   blend restarts from the current activity weights (the last tick's, whatever blend was running) with the
   transition's blend time B; the caller takes the new phase's captures from this tick's q and inputs and solves
   its rows in this tick.
6. Outputs for the QP, at the end of this tick's step: with t = ``elapsed`` + dt and s = t / B (1 when B = 0 or
   t reaches B), each phase's activity w_p = w0_p + s (n_p - w0_p), w0 the weights at the transition and n the
   new phase's indicator (clamped to [0, 1]): old phases ramp to 0 and the new one to 1, linear in time, and
   the weights are exactly one-hot once s = 1 (at once without a blend; w0 + (1 - w0) and w0 + (0 - w0) round to
   1 and 0 exactly: the tick's step then solves the phase's steady case, vfdsl.compiler.cases); they sum to 1 up to
   rounding, and an
   interrupted blend moves no weight by more than a regular step of dt/B. The funnel factor is 1 - s: 0 from the
   tick whose step ends at B on; a hard fixture of the phase violated by e at entry gets the tolerance
   declared + e * funnel (vfdsl.compiler.phases).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

FALSE, TRUE, UNKNOWN = 0, 1, 2
COMPARE, ELAPSED, UNCHANGED, LEAST_VIOLATION, LOGIC = range(5)
"""A monitor's kind: a compiled comparison (and its release), ``elapsed``, ``unchanged(INPUT)``, the previous tick's
least-violation status, a program over earlier monitors."""
GT, GE, LT, LE = range(4)
"""A time comparison's operator: >, >=, <, <=."""
AND, OR, NOT = -1, -2, -3
"""Postfix program operations; an entry m >= 0 pushes monitor m's value."""
MAX_STACK = 32
"""The deepest stack a program may need (its expression's nesting, plus one)."""
LEAST_VIOLATION_BIT = 1
"""vfdsl.runtime.qp.StepStatus.LEAST_VIOLATION."""


@dataclass(frozen=True)
class Monitor:
    """One monitor: ``kind`` and its operands (``raw``/``release``: indices into the tick's compiled values, -1 for
    no release; ``watch``: index into :attr:`MachineTable.watched`; ``op``, ``threshold`` (s): a time comparison;
    ``program``: postfix over earlier monitors), and its hold time (s, 0: none)."""

    kind: int
    raw: int = -1
    release: int = -1
    watch: int = -1
    op: int = GT
    threshold: float = 0.0
    program: tuple[int, ...] = ()
    hold: float = 0.0


@dataclass(frozen=True)
class Transition:
    """``source`` (a phase, -1: any other than ``target``) -> ``target`` when the postfix ``guard`` over monitors is TRUE, blending over
    ``blend`` s."""

    source: int
    target: int
    guard: tuple[int, ...]
    blend: float = 0.0


@dataclass(frozen=True)
class MachineTable:
    """A procedure's machine: phases (``final`` flags, the ``initial`` one), monitors in evaluation order, the
    watched inputs' slices of u (start, size), transitions in file order; ``raw_size``/``u_size``: the lengths of
    a tick's compiled values and inputs."""

    initial: int
    final: tuple[bool, ...]
    monitors: tuple[Monitor, ...]
    watched: tuple[tuple[int, int], ...]
    transitions: tuple[Transition, ...]
    raw_size: int
    u_size: int

    def __post_init__(self):
        n = len(self.final)
        if not 0 <= self.initial < n:
            raise ValueError(f"initial phase {self.initial} not among {n} phases")
        for start, size in self.watched:
            if start < 0 or size < 1 or start + size > self.u_size:
                raise ValueError(f"watched slice ({start}, {size}) outside u[{self.u_size}]")
        for i, m in enumerate(self.monitors):
            _check_monitor(self, i, m)
        for k, t in enumerate(self.transitions):
            if not (-1 <= t.source < n and 0 <= t.target < n) or not 0 <= t.blend < math.inf:
                raise ValueError(f"transition {k}: phases {t.source} -> {t.target} of {n}, blend {t.blend}")
            _check_program(t.guard, len(self.monitors), f"transition {k}'s guard")

    @property
    def phases(self) -> int:
        return len(self.final)

    def c_arrays(self) -> dict[str, list]:
        """The table as the C struct ``vfdsl_pm_table`` holds it: one list per array member (a monitor's ``a`` is
        its raw index, watched input or program start, ``b`` its release index or program length; every program
        in one ``code`` array)."""
        code: list[int] = []

        def place(program):
            code.extend(program)
            return len(code) - len(program), len(program)

        ab = [place(m.program) if m.kind == LOGIC else (m.raw if m.kind == COMPARE else m.watch, m.release)
              for m in self.monitors]
        guards = [place(t.guard) for t in self.transitions]
        offsets = [sum(size for _, size in self.watched[:w]) for w in range(len(self.watched))]
        return {"final": [int(f) for f in self.final], "kind": [m.kind for m in self.monitors],
                "a": [a for a, _ in ab], "b": [b for _, b in ab], "op": [m.op for m in self.monitors],
                "threshold": [m.threshold for m in self.monitors], "hold": [m.hold for m in self.monitors],
                "watch_start": [s for s, _ in self.watched], "watch_size": [n for _, n in self.watched],
                "watch_offset": offsets, "source": [t.source for t in self.transitions],
                "target": [t.target for t in self.transitions], "guard_start": [s for s, _ in guards],
                "guard_size": [n for _, n in guards], "blend": [t.blend for t in self.transitions], "code": code}


def _check_monitor(table: MachineTable, i: int, m: Monitor) -> None:
    if not (0 <= m.hold < math.inf and math.isfinite(m.threshold) and GT <= m.op <= LE):
        raise ValueError(f"monitor {i}: hold {m.hold}, threshold {m.threshold}, op {m.op}")
    if m.kind == COMPARE and not (0 <= m.raw < table.raw_size and -1 <= m.release < table.raw_size):
        raise ValueError(f"monitor {i}: compiled values {m.raw}, {m.release} outside raw[{table.raw_size}]")
    if m.kind == UNCHANGED and not 0 <= m.watch < len(table.watched):
        raise ValueError(f"monitor {i}: watched input {m.watch} of {len(table.watched)}")
    if m.kind == LOGIC:
        _check_program(m.program, i, f"monitor {i}")
    elif not COMPARE <= m.kind < LOGIC:
        raise ValueError(f"monitor {i}: unknown kind {m.kind}")


def _check_program(program: tuple[int, ...], monitors: int, what: str) -> None:
    """A postfix program over monitors [0, monitors) that leaves one value and never needs more than MAX_STACK."""
    depth = 0
    for op in program:
        if op >= monitors or op < NOT:
            raise ValueError(f"{what}: {op} is no operation or earlier monitor (of {monitors})")
        depth += 1 if op >= 0 else (0 if op == NOT else -1)
        if depth < 1 or depth > MAX_STACK:
            raise ValueError(f"{what}: program {program} is malformed or deeper than {MAX_STACK}")
    if depth != 1:
        raise ValueError(f"{what}: program {program} leaves {depth} values")


@dataclass
class MachineState:
    """The machine between ticks: the phase, its ``elapsed`` time, per monitor its latch, held time and this tick's
    value, per watched input component its last value and per watched input its ``unchanged`` time, the running
    blend (its B, the weights ``start`` at its transition), this tick's outputs (``weight`` per phase,
    ``funnel``) and the transition ``fired`` this tick (-1: none)."""

    phase: int
    weight: list[float]
    latch: list[int]
    held: list[float]
    value: list[int]
    last: list[float]
    unchanged: list[float]
    start: list[float] = field(default_factory=list)
    started: bool = False
    elapsed: float = 0.0
    blend: float = 0.0
    funnel: float = 0.0
    fired: int = -1

    @classmethod
    def initial(cls, table: MachineTable) -> MachineState:
        one_hot = [float(p == table.initial) for p in range(table.phases)]
        n = len(table.monitors)
        return cls(table.initial, one_hot, [0] * n, [0.0] * n, [FALSE] * n,
                   [math.nan] * sum(size for _, size in table.watched), [0.0] * len(table.watched), list(one_hot))


def _reached(t: float, T: float, dt: float) -> bool:
    return t >= T - 0.5 * dt


def _compare_time(t: float, op: int, T: float, dt: float) -> int:
    half = 0.5 * dt
    if op == GT:
        return int(t > T + half)
    if op == GE:
        return int(t >= T - half)
    if op == LT:
        return int(t < T - half)
    return int(t <= T + half)


def _run(code: tuple[int, ...], value: list[int]) -> int:
    """The postfix program's Kleene value."""
    stack: list[int] = []
    for op in code:
        if op >= 0:
            stack.append(value[op])
        elif op == NOT:
            stack.append(stack.pop() if stack[-1] == UNKNOWN else 1 - stack.pop())
        else:
            b, a = stack.pop(), stack.pop()
            absorbing = FALSE if op == AND else TRUE
            stack.append(absorbing if absorbing in (a, b) else (a if a == b else UNKNOWN))
    return stack[0]


def _condition(table: MachineTable, state: MachineState, i: int, m: Monitor, raw, u, dt: float,
               last_status: int) -> int:
    if m.kind == COMPARE:
        v = raw[m.release if m.release >= 0 and state.latch[i] else m.raw]
        if v != v:
            return UNKNOWN
        if m.release >= 0:
            state.latch[i] = int(v > 0.0)
        return int(v > 0.0)
    if m.kind == ELAPSED:
        return _compare_time(state.elapsed, m.op, m.threshold, dt)
    if m.kind == UNCHANGED:
        start, size = table.watched[m.watch]
        if any(x != x for x in u[start:start + size]):
            return UNKNOWN
        return _compare_time(state.unchanged[m.watch], m.op, m.threshold, dt)
    if m.kind == LEAST_VIOLATION:
        return int(last_status & LEAST_VIOLATION_BIT != 0)
    return _run(m.program, state.value)


def advance(table: MachineTable, state: MachineState, raw, u, dt: float, last_status: int) -> int:
    """One tick of the machine (the module's docstring, steps 1 to 6): updates ``state`` and returns the index of
    the transition fired, -1 for none."""
    if not (dt >= 0.0 and dt < math.inf):
        dt = 0.0
    if state.started:
        state.elapsed += dt
    state.started = True
    k = 0
    for w, (start, size) in enumerate(table.watched):
        same = True
        for j in range(size):
            x = u[start + j]
            same = same and x == state.last[k + j]
            state.last[k + j] = x
        state.unchanged[w] = state.unchanged[w] + dt if same else 0.0
        k += size
    for i, m in enumerate(table.monitors):
        c = _condition(table, state, i, m, raw, u, dt, last_status)
        state.held[i] = state.held[i] + dt if c == TRUE else 0.0
        state.value[i] = FALSE if c == TRUE and not _reached(state.held[i], m.hold, dt) else c
    state.fired = -1
    if not table.final[state.phase]:
        for k, t in enumerate(table.transitions):
            if (t.source == state.phase or (t.source < 0 and t.target != state.phase)) \
                    and _run(t.guard, state.value) == TRUE:
                state.fired, state.phase, state.elapsed, state.blend = k, t.target, 0.0, t.blend
                state.start[:] = state.weight
                break
    t = state.elapsed + dt
    s = 1.0 if state.blend <= 0.0 or _reached(t, state.blend, dt) else t / state.blend
    for p, w0 in enumerate(state.start):
        w = w0 + s * (float(p == state.phase) - w0)
        state.weight[p] = 0.0 if w < 0.0 else (1.0 if w > 1.0 else w)
    state.funnel = 1.0 - s
    return state.fired
