"""The tick's buffers, declared once: what one evaluation of a task's step reads and writes.

The step is ``step(q, u, p, dt, recover) -> (x, status, violation)`` (:func:`vfdsl.runtime.qp.build_step_function`;
a procedure's takes ``activity`` after dt, :func:`arguments`):
:data:`BUFFERS` lists its arguments, then its results, each with the task size that sets its length. Everything
that names them is derived from here: the step Function's argument and result names (runtime.qp), the runners'
arrays and :class:`Slot` (runtime.native), and the C appended to the generated header (:func:`c_declarations`:
the slot enum, the X-macro ``VFDSL_BUFFERS`` of names and sizes, and :func:`c_call`, the calling contract's
``arg``/``res`` line), which checked_step.h, stepper.c and the exported api.c use. A new buffer is one line here
(plus its use in the graph and in the C that reads or writes it).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Buffer:
    """One named buffer of the tick: ``size`` is ``"1"`` or a key of the task's sizes (:func:`lengths`); ``kind``
    is ``"data"`` (an argument of the task's compiled QP data), ``"phase"`` (an argument of a procedure's QP data
    only, :data:`PHASE_BUFFERS`), ``"step"`` (an argument of the step alone) or ``"result"``."""

    name: str
    size: str
    kind: str
    meaning: str


BUFFERS = (
    Buffer("q", "nq", "data", "the joint coordinates"),
    Buffer("u", "nu", "data", "every input's numbers, in declaration order"),
    Buffer("p", "np", "data", "the run-time params' numbers"),
    Buffer("dt", "1", "data", "the tick's period, s"),
    Buffer("recover", "1", "step", "nonzero: the least-violation phase is evaluated (the priming tick)"),
    Buffer("x", "nx", "result", "dq, then the slacks"),
    Buffer("status", "1", "result", "the StepStatus bits"),
    Buffer("violation", "rows", "result", "each general row's excess over its bounds"),
)
PHASE_BUFFERS = (
    Buffer("activity", "activity", "phase", "per phase its weight in [0, 1], then per phase 1: its hard rows on, "
           "then per funnelled hard constraint of a phase its funnel width (its tolerance's unit, >= 0)"),
)
"""A procedure's buffers, taken after ``dt``. A task without phases has none: its step and its generated C are
those of :data:`BUFFERS` alone, as before procedures; a procedure's header adds ``VFDSL_PROCEDURE``,
``VFDSL_ACTIVITY_ARG`` and ``VFDSL_ACTIVITY_LENGTH`` (codegen/build.py), read by checked_step.h and procedure_tick.h."""
ARGUMENTS = tuple(b.name for b in BUFFERS if b.kind != "result")
RESULTS = tuple(b.name for b in BUFFERS if b.kind == "result")
DATA_ARGUMENTS = tuple(b.name for b in BUFFERS if b.kind == "data")
"""The arguments of the task's QP data (``qp_data(q, u, p, dt)``), the first of the step's."""
PHASE_ARGUMENTS = tuple(b.name for b in PHASE_BUFFERS)
"""What a procedure's QP data and step take after ``dt``: ``qp_data(q, u, p, dt, activity)``."""
_KINDS = ("data", "step", "result")
assert [b.kind for b in BUFFERS] == sorted((b.kind for b in BUFFERS), key=_KINDS.index), "ordered by kind"
assert all(b.kind == "phase" for b in PHASE_BUFFERS)


def data_arguments(procedure: bool) -> tuple[str, ...]:
    """The arguments of a task's QP data: :data:`DATA_ARGUMENTS`, then :data:`PHASE_ARGUMENTS` for a procedure."""
    return DATA_ARGUMENTS + (PHASE_ARGUMENTS if procedure else ())


def arguments(procedure: bool) -> tuple[str, ...]:
    """The arguments of a task's step: its QP data's, then the step's own (``recover``)."""
    return data_arguments(procedure) + ARGUMENTS[len(DATA_ARGUMENTS):]


Slot = enum.IntEnum("Slot", [(b.name.upper(), k) for k, b in enumerate(BUFFERS)])
"""A buffer's index among all of them (C: ``VFDSL_<NAME>``): arguments from 0, results from ``len(ARGUMENTS)``."""


def lengths(**sizes: int) -> tuple[int, ...]:
    """Each buffer's length, in slot order, for the task's ``sizes`` (nq, nu, np, nx, rows)."""
    return tuple(1 if b.size == "1" else sizes[b.size] for b in BUFFERS)


def step_lengths(fn: ca.Function) -> tuple[int, ...]:
    """Each buffer's length in the step ``fn``, in slot order; ValueError when ``fn``'s arguments or results are
    not the declared ones."""
    if (tuple(fn.name_in()), tuple(fn.name_out())) != (ARGUMENTS, RESULTS):
        raise ValueError(f"the step {fn.name()!r} maps {fn.name_in()} to {fn.name_out()}; the tick's buffers are "
                         f"{list(ARGUMENTS)} to {list(RESULTS)}")
    return (*(fn.numel_in(i) for i in range(fn.n_in())), *(fn.numel_out(i) for i in range(fn.n_out())))


def c_call() -> str:
    """The arrays of one call, as the header's contract writes them: ``arg = {q, u, p, &dt, ...}, res = {...}``."""
    def listed(names):
        return ", ".join(("&" if b.size == "1" else "") + b.name for b in BUFFERS if b.name in names)
    return f"arg = {{{listed(ARGUMENTS)}}}, res = {{{listed(RESULTS)}}}"


def c_declarations(fn: ca.Function) -> str:
    """The C declarations of the step ``fn``'s buffers, for its generated header: the enum of slots (``VFDSL_Q``
    ..., ``VFDSL_N_BUFFERS``, ``VFDSL_N_ARGS``), their names as one string, and ``VFDSL_BUFFERS(F)``, which
    applies the macro ``F(slot, name, length)`` to every buffer in slot order."""
    sizes = step_lengths(fn)
    slots = ", ".join(f"VFDSL_{b.name.upper()}" for b in BUFFERS)
    each = " \\\n  ".join(f"F(VFDSL_{b.name.upper()}, {b.name}, {n})" for b, n in zip(BUFFERS, sizes, strict=True))
    meanings = "".join(f" *   {b.name:<10} {b.meaning}\n" for b in BUFFERS)
    return (f"\n#ifndef VFDSL_TICK_BUFFERS\n#define VFDSL_TICK_BUFFERS\n"
            f"/* The step's buffers (vfdsl/codegen/tick_buffers.py): arg[k] is slot k, res[k] slot VFDSL_N_ARGS + k.\n"
            f"{meanings} */\n"
            f"enum {{\n  {slots},\n  VFDSL_N_BUFFERS, VFDSL_N_ARGS = {len(ARGUMENTS)}\n}};\n"
            f"#define VFDSL_BUFFER_NAMES \"{', '.join(b.name for b in BUFFERS)}\"\n"
            f"#define VFDSL_BUFFERS(F) \\\n  {each}\n#endif\n")
