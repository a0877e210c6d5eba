"""``vfdsl.compile``: a checked task -> a Controller whose step is one call into generated C.

    IR --assemble--> qp_data Function --build_step_function--> step Function (QP data + DAQP + fallback)
       --build_library--> C source, shared library, metadata (cached by content hash) --> Controller

Without a C compiler the same step Function is evaluated by CasADi in the process (the interpreted
path): same answers, slower; a single warning says so.

A task with phases (a procedure) carries its machine in the generated C (codegen/procedure_tick.h: monitors, captures,
activity before each solve, run by the Python extension and the exported library); interpreted, or through CasADi's
loader of the C library (no Python headers), the machine runs in Python (:mod:`vfdsl.runtime.procedure`).
"""

from __future__ import annotations

import hashlib
import re
import warnings
from pathlib import Path

import casadi as ca

import vfdsl
from vfdsl.codegen.build import (BuiltLibrary, CompilerUnavailable, build_library, default_cache_dir,
                                 load_module)
from vfdsl.codegen.daqp_sources import DaqpSourcesUnavailable
from vfdsl.codegen.procedure_code import PhaseCode
from vfdsl.compiler.admissible import Admissible
from vfdsl.compiler.assemble import AssembledProblem, assemble
from vfdsl.compiler.cases import case_index, phase_cases
from vfdsl.compiler.phases import captures_function, monitor_values
from vfdsl.objectives.haptics import readout_function, teleop_terms
from vfdsl.errors import VfError
from vfdsl.files import path_value
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.controller import Controller, row_unit
from vfdsl.runtime.native import BufferedFunction, LockedRunner, NativeProcedure, StepperRunner
from vfdsl.runtime.procedure import Procedure, machine_table
from vfdsl.runtime.values import INPUT_UNITS, JOINT_UNITS, PARAM_UNITS, RuntimeValues
from vfdsl.runtime.qp import build_procedure_step, build_step_function
from vfdsl.runtime.teleoperation import Teleoperation

# Phase 1's answer meets every row and bound within this much (m or rad; LEVEL_ACCEPTANCE times it on a task with
# priority levels, vfdsl.runtime.qp): far below any tolerance a task can express.
FEASIBILITY_TOLERANCE = 1e-9
BACKENDS = ("auto", "native", "interpreted")
NAME_IN_SYMBOL = 48
"""Characters of the task name kept in its C symbol and file names (the IR hash keeps them unique)."""


class InterpretedFallback(UserWarning):
    """No C compiler: the controller runs interpreted (same answers, slower)."""


_warned = False


def ir_digest(task: ir.Task) -> str:
    """sha256 of the task's IR (its JSON form)."""
    return hashlib.sha256(task.model_dump_json().encode()).hexdigest()


def symbol_prefix(task: ir.Task, digest: str | None = None) -> str:
    """The C identifier of this task's step function: its name and a short hash of its IR, so that
    several tasks (or versions of one) can be loaded in one process."""
    digest = digest or ir_digest(task)
    name = re.sub(r"[^A-Za-z0-9_]", "_", task.name)[:NAME_IN_SYMBOL]   # file names stay short
    return f"vf_{name}_{digest[:8]}"


def compile(task: ir.Task, *, backend: str = "auto", cache_dir: str | Path | None = None) -> Controller:
    """A Controller for ``task``. ``backend``: 'native' (generated C, error without a compiler),
    'interpreted' (CasADi in this process), or 'auto' (native when a C compiler is found)."""
    controller, _ = build(task, backend=backend, cache_dir=cache_dir)
    return controller


def build(task: ir.Task, *, backend: str = "auto",
          cache_dir: str | Path | None = None) -> tuple[Controller, BuiltLibrary | None]:
    """As :func:`compile`, also returning the generated library (None on the interpreted path)."""
    global _warned
    task = ir.checked_task(task, "compile")
    if cache_dir is not None:
        cache_dir = path_value(cache_dir, "compile", "build cache folder (cache_dir)", "cache_dir='build/'")
    if backend not in BACKENDS:
        raise VfError(f"unknown backend '{backend}'; use one of {', '.join(BACKENDS)}")
    robot = Robot.load(task.robots[0].urdf)
    problem = assemble(task, robot)
    admissible = Admissible(task, robot.reach)
    values = RuntimeValues(task, problem.context.input_offsets, admissible, robot.lower, robot.upper,
                           robot.joint_names)
    digest = ir_digest(task)
    prefix = symbol_prefix(task, digest)
    def step(native: bool) -> ca.Function:
        options = dict(row_groups=problem.row_groups, feas_tol=FEASIBILITY_TOLERANCE, native=native,
                       last_level_is_cost=problem.last_level_is_damping)
        if task.phases:     # one step per phase, steady or blending, chosen each tick (vfdsl.compiler.cases)
            cases = phase_cases(problem, task)
            options.pop("last_level_is_cost")
            return build_procedure_step([(c.function, c.rows, c.last_level_is_damping) for c in cases],
                                        lambda activity: case_index(activity, len(task.phases)),
                                        len(problem.row_labels), prefix, **options)
        return build_step_function(problem.function, prefix, **options)

    readout = readout_function(task, problem)
    if backend != "interpreted":
        try:
            library = build_library(step(native=True), prefix, Path(cache_dir or default_cache_dir()),
                                    metadata(task, problem, values, digest), admissible.function,
                                    tuple(problem.context.c_sources.values()), values.input_checks,
                                    _phase_code(task, problem), readout)
            runner = _native_runner(values, problem, library, prefix)
            procedure = (NativeProcedure(task, runner, _machine(task, problem)[2])
                         if task.phases and isinstance(runner, StepperRunner) else _procedure(task, problem))
            teleoperation = None if readout is None else Teleoperation(
                BufferedFunction.native(library.so_path, f"{prefix}_teleop_readout"), problem.row_labels)
            return Controller(task, problem, values, runner, FEASIBILITY_TOLERANCE, procedure, teleoperation), library
        except (CompilerUnavailable, DaqpSourcesUnavailable) as exc:
            if backend == "native":
                raise
            if not _warned:
                warnings.warn(f"{exc.message}; running the controller interpreted (same answers, slower)",
                              InterpretedFallback, stacklevel=2)
                _warned = True
    runner = LockedRunner(BufferedFunction.interpreted(step(native=False)), values)
    teleoperation = None if readout is None else Teleoperation(BufferedFunction.interpreted(readout),
                                                               problem.row_labels)
    return Controller(task, problem, values, runner, FEASIBILITY_TOLERANCE, _procedure(task, problem),
                      teleoperation), None


def _procedure(task: ir.Task, problem: AssembledProblem) -> Procedure | None:
    """The run-time machine of a task with phases (None without)."""
    if not task.phases:
        return None
    ctx = problem.context
    return Procedure(task, ctx.layout, monitor_values(task, ctx), captures_function(task, ctx), ctx.input_offsets)


def _machine(task: ir.Task, problem: AssembledProblem):
    """A procedure's compiled monitor values, its machine's table and each named monitor's index in it."""
    ctx = problem.context
    values = monitor_values(task, ctx)
    return (values, *machine_table(task, values, ctx.input_offsets))


REAL_ARRAYS = ("threshold", "hold", "blend")
"""The members of the machine's C table (MachineTable.c_arrays) that are doubles; the others are ints."""


def _phase_code(task: ir.Task, problem: AssembledProblem) -> PhaseCode | None:
    """What a procedure's library holds beside its step (None without phases): its functions, its machine's table
    and where each phase's captures go in p."""
    if not task.phases:
        return None
    ctx = problem.context
    values, table, _ = _machine(task, problem)
    arrays = table.c_arrays()
    slots = [(k, ctx.layout.capture_slots[c.name]) for k, phase in enumerate(task.phases) for c in phase.captures]
    ints = {key: v for key, v in arrays.items() if key not in REAL_ARRAYS}
    ints.update(initial=[table.initial], raw_size=[table.raw_size], u_size=[table.u_size],
                capture_phase=[k for k, _ in slots], capture_offset=[s.offset for _, s in slots],
                capture_size=[s.size for _, s in slots])
    return PhaseCode(values.function, captures_function(task, ctx), ints, {key: arrays[key] for key in REAL_ARRAYS})


def _native_runner(values: RuntimeValues, problem: AssembledProblem, library: BuiltLibrary, prefix: str):
    """The generated step through the task's Python extension, or, when it could not be built (no
    Python headers), through CasADi's loader of the C library (same answers, the checks in Python)."""
    if library.module_path is not None:
        return StepperRunner(load_module(library.module_path), values, problem.nq + problem.n_slack,
                             len(problem.row_labels), problem.context.layout.defaults)
    return LockedRunner(BufferedFunction.native(library.so_path, prefix), values)


def _procedure_metadata(task: ir.Task, problem: AssembledProblem) -> dict:
    """A procedure's names for the C API: its phases, its named monitors with their index among the machine's
    monitors, its transitions in file order (source None: any)."""
    phases = [p.name for p in task.phases]
    named = _machine(task, problem)[2]
    return {"phases": phases, "monitors": [{"name": name, "index": k} for name, k in named.items()],
            "transitions": [{"source": None if tr.source is None else phases.index(tr.source),
                             "target": phases.index(tr.target), "guard": tr.text}
                            for tr in sorted(task.transitions, key=lambda tr: tr.order)]}


def metadata(task: ir.Task, problem: AssembledProblem, values: RuntimeValues, digest: str) -> dict:
    """What a caller of the generated library needs to know: layouts and units, the admissible run-time values
    (q's range, dt's range, the meaning of each check of the params), rows and where they come from."""
    ctx = problem.context
    admissible = values.admissible
    types = {d.name: d.type for d in task.inputs}
    runtime = [s.name for s in ctx.layout.slots.values() if s.size]     # the run-time params, in param_layout's order
    procedure = {} if not task.phases else {"procedure": _procedure_metadata(task, problem)}
    terms = teleop_terms(task)
    teleop = {} if not terms else {"teleop": {"terms": len(terms), "frame": terms[0].args["frame"].name}}
    return {**procedure, **teleop,
        "task": task.name,
        "file": task.file,
        "vfdsl_version": vfdsl.__version__,
        "ir_sha256": digest,
        "robot": task.robots[0].urdf,
        "joints": list(ctx.robot.joint_names),
        "joint_units": [JOINT_UNITS[kind] for kind in ctx.robot.joint_types],
        "q_admissible": {"lower": values.q_min.tolist(), "upper": values.q_max.tolist()},
        "start": None if task.start is None else [float(x) for x in task.start],
        "variables": {"dq": problem.nq, "slack": problem.n_slack},
        "input_layout": [{"name": name, "type": types[name], "unit": INPUT_UNITS[types[name]], "offset": offset,
                          "size": size}
                         for name, (offset, size) in ctx.input_offsets.items()],
        "param_layout": [{"name": s.name, "type": s.type, "unit": PARAM_UNITS.get(s.type, ""), "offset": s.offset,
                          "size": s.size}
                         for s in ctx.layout.slots.values() if s.size],
        "default_params": ctx.layout.defaults.tolist(),
        "param_checks": {"count": len(admissible.margins), "strict": admissible.strict.tolist(),
                         "meaning": admissible.margins.meanings,
                         "param": [runtime.index(c.param) if c.param in runtime else -1
                                   for c in admissible.margins.checks]},
        "period": task.scene.period,
        "min_period": values.dt_min,
        "max_period": values.dt_max,
        "dt_rule": values.dt_rule,
        "input_rule": values.input_rule,
        "feasibility_tolerance": FEASIBILITY_TOLERANCE,
        "rows": [{"label": str(label), "primitive": label.primitive, "frame": label.frame,
                  "file": label.span.file, "line": label.span.line, "group": group, "soft": label.soft,
                  "unit": row_unit(label.primitive)}
                 for label, group in zip(problem.row_labels, problem.row_groups)],
        "slacks": [{"label": str(label), "primitive": label.primitive, "file": label.span.file,
                    "line": label.span.line, "unit": row_unit(label.primitive)} for label in problem.slack_labels],
        "bounds": [[str(label) for label in labels] for labels in problem.bound_labels],
    }
