"""The Controller: a compiled task you call once per control tick.

    ctrl = vfdsl.compile(vfdsl.load("tasks/paper_b_virtual_rcm.vf"))      # see vfdsl.pipeline
    dq = ctrl.step(q, {"tau": [0, 0, 0.02]})           # joint increment for this tick
    qp = ctrl.problem(q, {"tau": [0, 0, 0.02]})        # the numeric QP behind it, one label per row

Everything is SI: q in m/rad, forces in N, torques in N m, dt in s. Inputs and params are checked before
anything is evaluated: an unknown name, a wrong length, NaN or inf raises :class:`~vfdsl.errors.VfError`.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from vfdsl.compiler.assemble import AssembledProblem, RowLabel
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS
from vfdsl.runtime.levels import PriorityLevel, priority_levels
from vfdsl.runtime.native import checked_step
from vfdsl.runtime.procedure import PhaseEvent, Procedure
from vfdsl.runtime.qp import StepStatus
from vfdsl.runtime.teleoperation import Teleoperation, TeleopOutput
from vfdsl.runtime.tracking import Tracking, readout, tracked_terms
from vfdsl.runtime.values import ASSUMED_PERIOD, RuntimeValues

_UNITS = {"length": "m", "angle": "rad"}


@dataclass(frozen=True)
class Violation:
    """A constraint the last step could not satisfy, and by how much, in its own SI unit: a hard row's
    excess, or a soft constraint's slack (how far the fixture is off); inf for a row that is undefined at this
    tick (its geometry not a number: a direction from captures that coincide), the tick then holding still."""

    label: RowLabel
    amount: float
    unit: str = ""

    def __str__(self) -> str:
        if self.amount == float("inf"):
            return f"{self.label}: undefined (its geometry has no direction at this tick: captured points that " \
                   "coincide?); the robot holds still"
        return f"{self.label}: violated by {self.amount:.3g} {self.unit}".rstrip()


@dataclass(frozen=True)
class FramePose:
    """A task frame as the controller sees it: origin (m), rotation (world <- frame), tool axis (unit)."""

    position: np.ndarray
    rotation: np.ndarray
    tool_axis: np.ndarray


@dataclass(frozen=True)
class QuadraticProgram:
    """One tick's QP:  minimize 1/2 x'Px + g'x  subject to  lb <= A x <= ub,  x = [dq; slacks].

    The first n rows of A are the identity (the variable bounds: joint limits, joint speeds, slack >= 0);
    the rest are the constraint rows. ``labels[i]`` says where row i comes from. P, g are the sum of the
    priority levels' costs (the least-violation phase's objective); ``levels`` gives each level's rows, targets
    and cost: what ``step()`` solves, level by level (each at its optimum over the optimal set of the levels above)."""

    P: np.ndarray
    g: np.ndarray
    A: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    labels: list[str]
    nq: int
    levels: list[PriorityLevel] = field(default_factory=list)


class Controller:
    """A compiled task: each tick checks its arguments and evaluates the QP and its solution with one
    call of the task's step (generated C, or the same graph interpreted by CasADi).

    Threads: every controller owns its solver memory (warm start included) and buffers, so controllers
    of one task run in parallel threads and give the same dq as alone; one controller called from two
    threads at once serialises the calls (a lock), never mixes them."""

    def __init__(self, task: ir.Task, problem: AssembledProblem, values: RuntimeValues, runner,
                 feasibility_tolerance: float, procedure: Procedure | None = None,
                 teleoperation: Teleoperation | None = None):
        self.task = task
        self.assembled = problem
        self.nq = problem.nq
        ctx = problem.context
        self.input_sizes = {d.name: d.size for d in task.inputs}
        self.param_names = [name for name, slot in ctx.layout.slots.items() if slot.size]
        self.param_defaults = {d.name: d.value for d in task.params if d.name in self.param_names}
        self.default_dt = task.scene.period
        self._values = values
        self._runner = runner
        self._procedure = procedure
        self._teleoperation = teleoperation
        self._teleop: TeleopOutput | None = None
        self._teleop_lock = threading.Lock()
        self._solve = runner.fast_step or self._solve
        if runner.fast_step is not None and teleoperation is None:  # the generated path: step is the task's C method
            self.step = runner.fast_step    # itself (the same checks, plain values in C, the rest by checked_step)
        self._tolerance = feasibility_tolerance
        self._labels = self._all_labels()
        self._units = [row_unit(label.primitive) for label in problem.row_labels]
        self._slack_units = [row_unit(label.primitive) for label in problem.slack_labels]
        self._phase_index = {phase.name: k for k, phase in enumerate(task.phases)}     # a phase weighs: activity[k] > 0
        if runner.kind == "native":
            self._prime()

    # -------------------------------------------------------------------------------------- API
    def step(self, q, inputs=None, params=None, dt=None) -> np.ndarray:
        """The joint increment dq for this tick (SI), from the joint coordinates q, every declared input,
        optionally params that replace their defaults for this tick, and dt (default: the scene's period; within
        [period / 100, 10 x period], :func:`~vfdsl.runtime.values.dt_range`: further is a unit slip). Each argument
        may be given by position or by keyword.

        Bad arguments (wrong type or shape, NaN or inf, unknown names, values out of their range) raise
        VfError before anything is evaluated. When the hard rows cannot all hold, dq solves the
        least-violation problem instead: ``status`` says so and :meth:`violations` names the rows. dq is
        always finite and within the joint bounds.

        A procedure's tick first runs its machine on these q and inputs (:mod:`vfdsl.runtime.procedure`): monitors,
        at most one transition (:attr:`phase`, :attr:`monitors`, :attr:`events`), captures, the phases' activity;
        then it solves the QP of the phase it is in after the transition.

        A task with a `teleop` term also reads out the haptic force, the set-point, following or not and the
        constraints that acted (:attr:`teleop`)."""
        if self._teleoperation is None:
            return self._solve(q, inputs, params, dt)
        with self._teleop_lock:     # the solve and its readout as one call: a second thread's tick waits between them
            dq = self._solve(q, inputs, params, dt)
            self._teleop = self._teleoperation.update(self._runner.data(), self._runner.x)   # this tick's buffers
            return dq

    def _solve(self, q, inputs=None, params=None, dt=None) -> np.ndarray:
        """The tick without the teleoperation readout (the generated path replaces it by the C method)."""
        if self._procedure is None:
            return checked_step(self._values, self._runner, q, inputs, params, dt)
        v = self._values
        q, u, p, dt = v.q(q), v.inputs(inputs), v.params(params, self._runner.margins), v.dt(dt)
        with self._procedure.lock:
            p = self._procedure.tick(q, u, p, dt, int(self._runner.status[0]))
            self._runner.activity[:] = self._procedure.activity
            return self._runner.run(q, u, p, dt, 0.0)

    @property
    def teleop(self) -> TeleopOutput | None:
        """The teleoperation readout of the last tick (:class:`~vfdsl.runtime.teleoperation.TeleopOutput`: haptic
        force, set-point, following, acting constraints); None before the first tick or without a teleop term."""
        return self._teleop

    @property
    def phase(self) -> str | None:
        """The procedure's phase after the last tick (its initial phase before the first); None without phases."""
        return None if self._procedure is None else self._procedure.phase

    @property
    def monitors(self) -> dict[str, bool]:
        """Each named monitor of the procedure: whether it held at the last tick ({} without phases)."""
        return {} if self._procedure is None else self._procedure.monitors

    @property
    def events(self) -> tuple[PhaseEvent, ...]:
        """The transitions of the last tick (at most one; () without phases)."""
        return () if self._procedure is None else self._procedure.events

    @property
    def captures(self) -> dict[str, np.ndarray]:
        """Each captured value of the procedure as it holds it after the last tick, in SI (a point in m, a
        direction a unit vector, an input in its SI unit; every capture holds its start value after the first tick
        until its phase is entered); {} without phases."""
        if self._procedure is None:
            return {}
        if self._runner.kind == "native":       # the C's buffer, copied under its lock
            p = self._runner.results()[3]
        else:
            with self._procedure.lock:
                p = self._procedure.p.copy()
        return {name: p[slot.offset:slot.offset + slot.size]
                for name, slot in self.assembled.context.layout.capture_slots.items()}

    def reset(self) -> None:
        """A procedure back to its initial phase, its captures retaken at the next tick (the solver's warm start
        is kept), the teleoperation readout to its first tick; nothing to do for a task without either. Under the
        ticks' locks: a tick in another thread runs before or after it, never on a machine half reset."""
        if self._procedure is not None:
            with self._procedure.lock:
                self._procedure.reset()
        if self._teleoperation is not None:
            with self._teleop_lock:
                self._teleoperation.reset()
                self._teleop = None

    def param_vector(self, params=None) -> np.ndarray | None:
        """The flat run-time param vector the step is given for ``params`` (checked as :meth:`step` checks them),
        or None for the defaults."""
        return self._values.params(params)

    def problem(self, q, inputs=None, params=None, dt=None) -> QuadraticProgram:
        """The numeric QP of this tick (before the solver's safeguards), one label per row; a procedure's with the
        captures and the phases' activity of its last tick (the machine does not advance)."""
        outputs = [np.array(x) for x in self.assembled.function(*self._data(q, inputs, params, dt))]
        H, g, A, lba, uba, lbx, ubx = outputs[:7]
        n = H.shape[0]
        return QuadraticProgram(P=H, g=g.ravel(), A=np.vstack([np.eye(n), A]),
                                lb=np.concatenate([lbx.ravel(), lba.ravel()]),
                                ub=np.concatenate([ubx.ravel(), uba.ravel()]),
                                labels=list(self._labels), nq=self.nq,
                                levels=priority_levels(outputs, self.assembled.levels))

    def tracking(self, q, inputs=None, params=None, dt=None) -> list[Tracking]:
        """Runs the tick (as :meth:`step`) and says, for every part of every `track` term held in every phase and
        of the procedure's phase after the tick, the commanded and the achieved rate and, when less than 99 % of
        the command is achieved, what holds it back (rows at their bounds, joints at their speed or position
        limits, by label)."""
        self.step(q, inputs, params, dt)
        args = self._data(q, inputs, params, dt)[:4]
        names, phases, rows = self._tracked
        shown = [phase is None or phase == self.phase for phase in phases]
        return readout(names, rows(*args), np.array(self._runner.x), self.nq, float(args[3]),
                       self.problem(q, inputs, params, dt), shown)

    @property
    def tracked_parts(self):
        """(names, Function (q, u, p, dt) -> E_1, f_1, E_2, f_2, ...) of every tracked part, every phase's included:
        its rows (dq -> rate, divided by dt) and its commanded rate (:func:`vfdsl.runtime.tracking.tracked_terms`)."""
        names, _, rows = self._tracked
        return names, rows

    @cached_property
    def _tracked(self):
        return tracked_terms(self.task, self.assembled)

    def frames(self, q) -> dict[str, FramePose]:
        """Every task frame's pose at q, from the controller's own kinematics (what the fixture sees)."""
        values = self._frames_function(self._values.q(q))
        poses = {}
        for k, name in enumerate(d.name for d in self.task.frames):
            p, R, axis = (np.array(values[3 * k + i]) for i in range(3))
            poses[name] = FramePose(position=p.ravel(), rotation=R, tool_axis=axis.ravel())
        return poses

    @property
    def status(self) -> StepStatus:
        """How the last step went: OPTIMAL, or LEAST_VIOLATION, BOUNDS_CLIPPED and FALLBACK flags."""
        return StepStatus(int(self._runner.status[0]))

    def violations(self) -> list[Violation]:
        """What the last step leaves violated: hard rows (excess over their bound) and soft constraints
        (their slack: how far the fixture is off), each in its SI unit. Empty after a step that meets
        every constraint. A procedure's phase that weighs nothing has no violation (its hard rows are off, its
        slacks free). Read from one copy of the tick's results, taken under its lock (a tick in another thread
        comes before or after it)."""
        x, _, violation, _, activity = self._runner.results()
        rows = self.assembled.row_labels
        found = [Violation(label, float(a), unit) for label, a, unit
                 in zip(rows, violation, self._units) if a > 0 and not label.soft]
        found += [Violation(label, float(s), unit) for label, s, unit
                  in zip(self.assembled.slack_labels, x[self.nq:], self._slack_units)
                  if s > self._tolerance and (label.phase is None or activity[self._phase_index[label.phase]] > 0.0)]
        return found

    @property
    def backend(self) -> str:
        """'native' (generated C) or 'interpreted' (CasADi in this process)."""
        return self._runner.kind

    @property
    def row_labels(self) -> list[RowLabel]:
        """Structured labels of the constraint rows (the rows of A after the variable bounds)."""
        return list(self.assembled.row_labels)

    # ------------------------------------------------------------------------------- internals
    def _data(self, q, inputs, params, dt) -> tuple:
        """The checked arguments of the task's QP data (a procedure's: its full params and activity)."""
        v = self._values
        p = v.params(params, self._runner.margins)
        if self._procedure is None:
            return v.q(q), v.inputs(inputs), self.assembled.context.layout.defaults if p is None else p, v.dt(dt)
        full = self._procedure.p.copy()
        full[:v.layout.size] = v.layout.defaults if p is None else p
        return v.q(q), v.inputs(inputs), full, v.dt(dt), self._procedure.activity.copy()

    def _prime(self) -> None:
        """Two evaluations at the start configuration, one with phase 2 forced (input ``recover``) and one through
        the priority levels; a procedure's in each case of its step (each phase steady, then a blend:
        vfdsl.compiler.cases), then its machine back to the initial phase: every DAQP workspace of the generated
        step is allocated now, so that no later step allocates memory. The C (Stepper.prime, an export's _new)
        primes in the same order, so that every path starts its ticks from the same warm starts."""
        start = self.task.start if self.task.start is not None else np.zeros(self.nq)
        u = np.zeros(sum(self.input_sizes.values()))
        self._runner.prime(np.asarray(start, dtype=float), u, self.default_dt or ASSUMED_PERIOD, len(self.task.phases))

    @cached_property
    def _frames_function(self) -> ca.Function:
        ctx = self.assembled.context
        outputs = []
        for decl in self.task.frames:
            frame = ctx.frame(decl.name)
            outputs += [frame.p, frame.R, frame.axis]
        return ca.Function("frames", [ctx.q], outputs)

    def _all_labels(self) -> list[str]:
        bounds = []
        for i, joint_labels in enumerate(self.assembled.bound_labels):
            joint = self.assembled.context.robot.joint_names[i]
            bounds.append(f"bounds of joint {joint}: " + ("; ".join(map(str, joint_labels)) or "none"))
        bounds += [f"slack >= 0 of {label}" for label in self.assembled.slack_labels]
        return bounds + [str(label) for label in self.assembled.row_labels]


def row_unit(primitive: str) -> str:
    """The unit of a primitive's rows: its tolerance's, or (without a tolerance) what its rows bound."""
    spec = CONSTRAINTS.get(primitive)
    if spec is None:
        return ""
    return _UNITS.get(spec.tolerance, "") if spec.tolerance else spec.row_unit
