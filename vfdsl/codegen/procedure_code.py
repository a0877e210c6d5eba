"""A procedure's part of its task's generated library: the functions beside the step and the header's declarations.

The library of a task with phases holds, beside its step, ``<prefix>_monitor_values`` and ``<prefix>_captures``
(:mod:`vfdsl.compiler.phases`), and its header the phase buffers' places and the phase machine's table as constant
arrays, which procedure_tick.h reads (docs/runtime.md, "The compiled procedure").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from vfdsl.codegen.tick_buffers import ARGUMENTS, PHASE_BUFFERS, RESULTS, c_call, c_declarations

PROCEDURE_TICK = (Path(__file__).parent / "procedure_tick.h", Path(__file__).parent / "phase_machine.h")
"""A procedure's tick in plain C (its machine, captures, activity), included with checked_step.h."""


@dataclass(frozen=True)
class PhaseCode:
    """What a procedure's library holds beside its step: ``monitor_values(q, u, p) -> raw`` and ``captures(q, u, p)
    -> per phase its values`` (:mod:`vfdsl.compiler.phases`), exported as ``<prefix>_monitor_values`` and
    ``<prefix>_captures``, and the machine's table (``MachineTable.c_arrays()``, with ``initial``, ``raw_size`` and
    ``u_size`` as one-number arrays) with the captures' layout (per capture in phase order its ``capture_phase``,
    ``capture_offset`` in p and ``capture_size``), written into the header as constant arrays: ``arrays`` of ints,
    ``reals`` of doubles."""

    monitor_values: ca.Function
    captures: ca.Function
    arrays: dict[str, list[int]]
    reals: dict[str, list[float]]


def functions(phases: PhaseCode, prefix: str) -> tuple[tuple[ca.Function, str], ...]:
    """The procedure's functions and their C names, generated with the step."""
    return (phases.monitor_values, f"{prefix}_monitor_values"), (phases.captures, f"{prefix}_captures")


def header(fn: ca.Function, phases: PhaseCode, contract: str) -> str:
    """The procedure's step ``fn``'s part of its header: the calling ``contract`` (its ``@CALL@`` filled), the
    declarations of the buffers every step has, then the phase buffers and the machine."""
    return (contract.replace("@CALL@", _phase_call()) + c_declarations(_phase_less(fn))
            + _phase_declarations(fn, phases))


def _phase_less(fn: ca.Function) -> ca.Function:
    """A stand-in of the procedure's step ``fn`` with its buffers but the phase's (for their sizes only): the
    declarations of :data:`~vfdsl.codegen.tick_buffers.BUFFERS` are those of every step."""
    args = [ca.SX.sym(name, fn.numel_in(fn.index_in(name))) for name in ARGUMENTS]
    results = [ca.SX(fn.numel_out(fn.index_out(name)), 1) for name in RESULTS]
    return ca.Function(fn.name(), args, results, list(ARGUMENTS), list(RESULTS))


def _phase_call() -> str:
    """A procedure's call: :func:`~vfdsl.codegen.tick_buffers.c_call`'s, with the phase's buffers in place."""
    return c_call() + ", and " + ", ".join(f"arg[VFDSL_{b.name.upper()}_ARG] = {b.name}" for b in PHASE_BUFFERS)


def _phase_declarations(fn: ca.Function, phases: PhaseCode) -> str:
    """A procedure's part of the header: per phase buffer its index among the step's arguments (the later
    arguments move one on) and its length in ``fn``, and the machine's arrays as ``static const`` C arrays named
    ``vfdsl_pt_<key>`` with their lengths ``VFDSL_PT_<KEY>`` (each array has one more, unused, entry: never empty),
    for codegen/procedure_tick.h."""
    lines = ["\n#ifndef VFDSL_PROCEDURE\n#define VFDSL_PROCEDURE 1",
             "/* A procedure's step: its phase buffers' argument index and length, its machine (procedure_tick.h). */"]
    for b in PHASE_BUFFERS:
        index = fn.index_in(b.name)
        lines += [f"#define VFDSL_{b.name.upper()}_ARG {index}",
                  f"#define VFDSL_{b.name.upper()}_LENGTH {fn.numel_in(index)}"]
    for key, values in {**phases.arrays, **phases.reals}.items():
        real = key in phases.reals
        text = ", ".join(repr(float(v)) if real else str(int(v)) for v in [*values, 0])
        lines += [f"#define VFDSL_PT_{key.upper()} {len(values)}",
                  f"static const {'double' if real else 'int'} vfdsl_pt_{key}[] = {{{text}}};"]
    return "\n".join(lines) + "\n#endif\n"
