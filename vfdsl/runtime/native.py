"""Call a CasADi Function on preallocated numpy buffers: generated C or interpreted, one interface.

Both paths go through CasADi's ``Function.buffer()``: the input and output arrays are bound once,
a call copies the inputs in, runs one evaluation and returns the (same) output arrays. On the
native path the Function is ``casadi.external(name, so_path)``, so an evaluation is one direct
call into the generated C; on the interpreted path it is the CasADi Function itself, evaluated by
CasADi's virtual machine.

Measured (docs/runtime.md): the bare ``buffer()`` evaluation costs 0.07 us of call overhead, against
0.7 us for a ctypes call of the same C function with prebuilt pointer arrays; :meth:`evaluate` (with
its return-code check) 0.5 us and :meth:`__call__` with four array inputs 1.7 us.

Not thread-safe: one instance owns one set of buffers and one solver memory; :class:`LockedRunner`
serialises its callers.

A *runner* is what a :class:`~vfdsl.runtime.controller.Controller` calls each tick:
``run(q, u, p, dt, recover) -> dq`` on checked float64 arrays (``p`` None: the task's default params),
the arrays ``x``, ``status`` and ``violation`` of its last evaluation, ``margins`` (p -> the task's column of
checks, :mod:`vfdsl.compiler.admissible`), and ``fast_step``, an optional
``(q, inputs, params, dt) -> dq``: the whole of Controller.step in C, which checks plain arguments itself and hands
anything else to :func:`checked_step`. :class:`StepperRunner` runs the generated C through the task's Python extension
(``vfdsl/codegen/stepper.c``): own memory slot, GIL released during the solve, a fast path in C;
:class:`LockedRunner` runs a :class:`BufferedFunction` (interpreted, or the C library through CasADi
when no Python headers were there to build the extension).
"""

from __future__ import annotations

import threading
from pathlib import Path

import casadi as ca
import numpy as np

from vfdsl.codegen.tick_buffers import ARGUMENTS, DATA_ARGUMENTS, PHASE_ARGUMENTS, Slot, lengths
from vfdsl.errors import VfError
from vfdsl.ir import model as ir
from vfdsl.runtime import phase_machine as pm
from vfdsl.runtime.procedure import PhaseEvent
from vfdsl.runtime.values import RuntimeValues


def checked_step(values: RuntimeValues, runner, q, inputs=None, params=None, dt=None) -> np.ndarray:
    """Controller.step through the Python checks (which explain what is wrong: VfError), then ``runner.run``: the
    interpreted path, and the generated one's for the values its C fast path does not take (``runner`` is then the
    task's Stepper, which has the same ``run`` and ``margins``)."""
    return runner.run(values.q(q), values.inputs(inputs), values.params(params, runner.margins), values.dt(dt), 0.0)


class BufferedFunction:
    """``f(*inputs) -> tuple of output arrays`` with no array allocation per call.

    Inputs and outputs must be dense. Column vectors are 1-D arrays, matrices are column-major
    (``order='F'``) 2-D arrays. The returned arrays are overwritten by the next call: copy to keep.
    """

    def __init__(self, function: ca.Function, kind: str):
        self.function = function
        self.kind = kind
        self.name = function.name()
        buffer, self._evaluate = function.buffer()
        self._buffer = buffer
        self._inputs = tuple(_bind(buffer.set_arg, i, function.sparsity_in(i), f"input {name!r}")
                             for i, name in enumerate(function.name_in()))
        self._outputs = tuple(_bind(buffer.set_res, i, function.sparsity_out(i), f"output {name!r}")
                              for i, name in enumerate(function.name_out()))

    @classmethod
    def native(cls, so_path: Path | str, name: str) -> BufferedFunction:
        """Function ``name`` of the generated shared library ``so_path``."""
        try:
            function = ca.external(name, str(so_path))
        except RuntimeError as e:
            raise VfError(f"cannot load {name!r} from {so_path}: {e}") from e
        return cls(function, "native")

    @classmethod
    def interpreted(cls, function: ca.Function) -> BufferedFunction:
        """The same Function evaluated by CasADi in this process (no C compiler needed)."""
        return cls(function, "interpreted")

    @property
    def outputs(self) -> tuple[np.ndarray, ...]:
        """The bound output arrays, overwritten by each evaluation."""
        return self._outputs

    @property
    def inputs(self) -> tuple[np.ndarray, ...]:
        """The bound input arrays: writing into them and calling :meth:`evaluate` skips the copy."""
        return self._inputs

    def __call__(self, *args) -> tuple[np.ndarray, ...]:
        if len(args) != len(self._inputs):
            raise VfError(f"{self.name} takes {len(self._inputs)} inputs, got {len(args)}")
        for i, (array, value) in enumerate(zip(self._inputs, args, strict=True)):
            if getattr(value, "shape", None) != array.shape:
                value = self._conform(i, value)
            array[...] = value
        return self.evaluate()

    def _conform(self, i: int, value) -> np.ndarray:
        """``value`` reshaped to input i's buffer; never broadcast (a scalar is not a vector)."""
        array = self._inputs[i]
        value = np.asarray(value, dtype=float)
        if value.size != array.size:
            raise VfError(f"{self.name}: input {self.function.name_in(i)!r} needs {array.size} "
                          f"values, got {value.size}")
        return value.reshape(array.shape, order="F")

    def evaluate(self) -> tuple[np.ndarray, ...]:
        """Evaluate on the current contents of :attr:`inputs`."""
        self._evaluate()
        code = self._buffer.ret()
        if code:
            raise VfError(f"{self.kind} function {self.name!r} failed with return code {code}")
        return self._outputs


def _bind(set_buffer, i: int, sparsity: ca.Sparsity, what: str) -> np.ndarray:
    """A zeroed array bound as buffer i: 1-D for a column vector, else a column-major view."""
    if not sparsity.is_dense():
        raise ValueError(f"{what} is sparse; densify it in the graph")
    storage = np.zeros(sparsity.numel())
    set_buffer(i, memoryview(storage))
    rows, cols = sparsity.shape
    return storage if cols == 1 else storage.reshape((rows, cols), order="F")


class LockedRunner:
    """A BufferedFunction behind a lock: callers from several threads are serialised. A procedure's step also reads
    :attr:`activity`, which its caller writes before :meth:`run` (None for a task without phases)."""

    fast_step = None

    def __init__(self, function: BufferedFunction, values: RuntimeValues):
        self.kind = function.kind
        self.nq = values.nq
        self.margins = values.admissible.function        # p -> the column of checks, interpreted
        self._function = function
        self._p_default = values.layout.defaults
        self._lock = threading.Lock()
        inputs = dict(zip(function.function.name_in(), function.inputs, strict=True))
        self._arguments = tuple(inputs[name] for name in ARGUMENTS)
        self.activity = inputs.get(PHASE_ARGUMENTS[0])
        self.x, self.status, self.violation = function.outputs       # the step's RESULTS

    def prime(self, q, u, dt: float, n_phases: int) -> None:
        """The step with and without recovery (Controller._prime); a procedure's in each of its cases
        (vfdsl.compiler.cases: each phase steady, then phase 0 at half weight, a blend; codegen/procedure_tick.h's
        vfdsl_procedure_prime, in the same order), the activity then back to the phase buffer's initial value."""
        if not n_phases:
            for recover in (1.0, 0.0):
                self.run(q, u, None, dt, recover)
            return
        initial = self.activity.copy()
        for k in range(n_phases + 1):
            self.activity[:] = 0.0
            self.activity[k % n_phases] = self.activity[n_phases + k % n_phases] = 1.0
            if k == n_phases:
                self.activity[0] = 0.5
            for recover in (1.0, 0.0):
                self.run(q, u, None, dt, recover)
        self.activity[:] = initial

    def results(self) -> tuple:
        """(x, status, violation, p, activity or None): copies of the last evaluation's results, its params and (a
        procedure's) activity, taken under the lock: another thread's evaluation comes before or after, never
        between two of them."""
        with self._lock:
            return (self.x.copy(), self.status.copy(), self.violation.copy(), self._arguments[2].copy(),
                    None if self.activity is None else self.activity.copy())

    def data(self) -> tuple[np.ndarray, ...]:
        """The QP data arguments of the last evaluation (q, u, p, dt, and a procedure's activity), as its buffers
        hold them (overwritten by the next)."""
        return self._arguments[:len(DATA_ARGUMENTS)] + (() if self.activity is None else (self.activity,))

    def run(self, q, u, p, dt: float, recover: float) -> np.ndarray:
        with self._lock:
            arguments = (q, u, self._p_default if p is None else p, dt, recover)
            for buffer, value in zip(self._arguments, arguments, strict=True):
                buffer[...] = value
            self._function.evaluate()
            return self.x[:self.nq].copy()


class StepperRunner:
    """The task's Python extension: a ``Stepper`` with its own memory slot of the generated code, whose fast
    path checks params with the generated column of checks (``margins``). A procedure's (``defaults``: its full
    params' defaults, the captures' slots after the params) runs its machine in C before each solve of ``step`` and
    of the checked path (``Stepper.tick``); :attr:`p` holds the full params of the last tick."""

    kind = "native"

    def __init__(self, module, values: RuntimeValues, n: int, m: int, defaults: np.ndarray | None = None):
        layout = values.layout
        defaults = layout.defaults if defaults is None else defaults
        arrays = tuple(np.zeros(k) for k in lengths(nq=values.nq, nu=values.n_inputs, np=defaults.size, nx=n, rows=m))
        self.x, self.status, self.violation = _results(arrays)
        names = tuple(values.input_offsets)
        slots = [slot for slot in layout.slots.values() if slot.size]
        dt_default = values.default_period
        try:
            self.stepper = module.Stepper(arrays, np.ascontiguousarray(defaults, dtype=float), names,
                                          tuple(values.input_offsets[k][0] for k in names),
                                          tuple(values.input_offsets[k][1] for k in names),
                                          np.concatenate([values.q_min, values.q_max]).astype(float),
                                          float("nan") if dt_default is None else float(dt_default),
                                          values.dt_min, values.dt_max, tuple(slot.name for slot in slots),
                                          tuple(slot.offset for slot in slots), tuple(slot.size for slot in slots),
                                          tuple(slot.type == "curve" for slot in slots), values.admissible.strict)
        except RuntimeError as e:
            raise VfError(f"cannot start another controller of this task: {e}",
                          hint="close (delete) controllers you no longer use") from None
        self.p = arrays[Slot.P]
        procedure = hasattr(self.stepper, "tick")
        self._data = tuple(arrays[slot] for slot in (Slot.Q, Slot.U, Slot.P, Slot.DT))
        self._procedure = procedure

        def full(p):
            """The params ``p`` (the caller's) with the captures' slots after them, for the C."""
            out = defaults.copy()
            out[:p.size] = p
            return out

        def step(stepper, q, inputs=None, params=None, dt=None):    # (holds the values, not the stepper: no cycle)
            if not procedure:
                return checked_step(values, stepper, q, inputs, params, dt)
            p = values.params(params, lambda p: stepper.margins(full(p)))
            return stepper.tick(values.q(q), values.inputs(inputs), None if p is None else full(p),
                                values.dt(dt))
        step.__qualname__ = "Controller.step"       # (as Python's errors name a wrong call: the one the user made)
        self.stepper.checked = step
        self.fast_step = self.stepper.step
        self.run = self.stepper.run
        self.results = self.stepper.results     # (x, status, violation, p, activity or None), under the C's lock
        margins = self.stepper.margins
        self.margins = (lambda p: margins(full(p))) if procedure else margins

    def data(self) -> tuple[np.ndarray, ...]:
        """The QP data arguments of the last tick (q, u, p, dt, and a procedure's activity), as the Stepper's
        buffers hold them (overwritten by the next)."""
        return self._data + ((self.stepper.machine()[4],) if self._procedure else ())

    def prime(self, q, u, dt: float, n_phases: int) -> None:
        """Controller._prime in the C (Stepper.prime, which knows the procedure's phases)."""
        self.stepper.prime(q, u, dt)


class NativeProcedure:
    """A procedure whose machine runs in the generated C (codegen/procedure_tick.h, inside the Stepper's ticks): what
    :class:`~vfdsl.runtime.controller.Controller` reads of a :class:`~vfdsl.runtime.procedure.Procedure` (phase,
    monitors, events, activity, full params, reset), read from the Stepper after its last tick. ``named``: each named
    monitor's index among the machine's (:func:`vfdsl.runtime.procedure.machine_table`)."""

    def __init__(self, task: ir.Task, runner: StepperRunner, named: dict[str, int]):
        self.task = task
        self._stepper = runner.stepper
        self._named = named
        self._transitions = sorted(task.transitions, key=lambda tr: tr.order)
        self.p = runner.p
        self.lock = threading.Lock()

    @property
    def phase(self) -> str:
        return self.task.phases[self._stepper.machine()[0]].name

    @property
    def monitors(self) -> dict[str, bool]:
        values = self._stepper.machine()[5]
        return {name: bool(values[k] == pm.TRUE) for name, k in self._named.items()}

    @property
    def events(self) -> tuple[PhaseEvent, ...]:
        phase, source, fired, time, _, _ = self._stepper.machine()
        if fired < 0:
            return ()
        phases = self.task.phases
        return (PhaseEvent(phases[source].name, phases[phase].name, self._transitions[fired].text, time),)

    @property
    def activity(self) -> np.ndarray:
        return self._stepper.machine()[4]

    def reset(self) -> None:
        self._stepper.reset()


def _results(buffers: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """(x, status, violation) among a step's buffers (its arguments, then its results)."""
    return buffers[Slot.X], buffers[Slot.STATUS], buffers[Slot.VIOLATION]
