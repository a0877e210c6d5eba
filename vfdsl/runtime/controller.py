"""The Controller: a compiled task you call once per control tick.

    ctrl = vfdsl.compile(vfdsl.load("tasks/paper_b_virtual_rcm.vf"))      # see vfdsl.pipeline
    dq = ctrl.step(q, {"tau": [0, 0, 0.02]})           # joint increment for this tick
    qp = ctrl.problem(q, {"tau": [0, 0, 0.02]})        # the numeric QP behind it, one label per row

Everything is SI: q in m/rad, forces in N, torques in N m, dt in s. Inputs and params are checked before
anything is evaluated: an unknown name, a wrong length, NaN or inf raises :class:`~vfdsl.errors.VfError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel

from vfdsl.compiler.assemble import AssembledProblem, RowLabel
from vfdsl.compiler.context import PARAM_SIZES, flatten
from vfdsl.errors import VfError, suggest
from vfdsl.ir import model as ir
from vfdsl.runtime.native import BufferedFunction
from vfdsl.runtime.qp import StepStatus


@dataclass(frozen=True)
class Violation:
    """A hard row the last step could not satisfy, and by how much (in the row's units: m or rad)."""

    label: RowLabel
    amount: float

    def __str__(self) -> str:
        return f"{self.label}: violated by {self.amount:.3g}"


@dataclass(frozen=True)
class QuadraticProgram:
    """One tick's QP:  minimize 1/2 x'Px + g'x  subject to  lb <= A x <= ub,  x = [dq; slacks].

    The first n rows of A are the identity (the variable bounds: joint limits, joint speeds, slack >= 0);
    the rest are the constraint rows. ``labels[i]`` says where row i comes from."""

    P: np.ndarray
    g: np.ndarray
    A: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    labels: list[str]
    nq: int


class Controller:
    """A compiled task: each tick evaluates its QP and solves it with one call to its step function
    (generated C, or the same graph interpreted by CasADi)."""

    def __init__(self, task: ir.Task, problem: AssembledProblem, step: BufferedFunction):
        self.task = task
        self.assembled = problem
        self.nq = problem.nq
        ctx = problem.context
        self.input_sizes = {d.name: d.size for d in task.inputs}
        self.param_names = [d.name for d in task.params if PARAM_SIZES[d.type] > 0]
        self.param_defaults = {d.name: d.value for d in task.params if PARAM_SIZES[d.type] > 0}
        self.default_dt = task.scene.period
        self._layout = ctx.layout
        self._input_offsets = ctx.input_offsets
        self._u = np.zeros(ctx.u.shape[0])
        self._p_default = ctx.layout.defaults.copy()
        self._step = step
        self._labels = self._all_labels()
        self._status = np.zeros(1)
        self._violation = np.zeros(0)
        self._default_params_in_buffer = False
        if step.kind == "native":
            self._prime()

    # -------------------------------------------------------------------------------------- API
    def problem(self, q, inputs=None, params=None, dt=None) -> QuadraticProgram:
        args = self._arguments(q, inputs, params, dt)
        H, g, A, lba, uba, lbx, ubx = (np.array(v) for v in self.assembled.function(*args))
        n = H.shape[0]
        return QuadraticProgram(P=H, g=g.ravel(), A=np.vstack([np.eye(n), A]),
                                lb=np.concatenate([lbx.ravel(), lba.ravel()]),
                                ub=np.concatenate([ubx.ravel(), uba.ravel()]),
                                labels=list(self._labels), nq=self.nq)

    def step(self, q, inputs=None, params=None, dt=None) -> np.ndarray:
        """The joint increment dq for this tick (checked inputs, one solver call).

        When the hard rows cannot all hold, dq solves the least-violation problem instead: ``status``
        says so and :meth:`violations` names the rows. dq is always finite and within the joint bounds."""
        q_buf, u_buf, p_buf, dt_buf, _ = self._step.inputs
        inputs = {} if inputs is None else inputs
        if not self._write_unchecked(q, inputs, q_buf, u_buf):     # anything unusual: the detailed checks
            q_buf[:] = _finite_vector(q, self.nq, "q (joint coordinates)")
            u_buf[:] = self._inputs(inputs)
        if params or not self._default_params_in_buffer:
            p_buf[:] = self._params(params or {})
            self._default_params_in_buffer = not params
        dt_buf[...] = self._dt(dt)
        x, self._status, self._violation = self._step.evaluate()
        return x[:self.nq].copy()

    @property
    def status(self) -> StepStatus:
        """How the last step went: OPTIMAL, or LEAST_VIOLATION (and BOUNDS_CLIPPED, FALLBACK) flags."""
        return StepStatus(int(self._status[0]))

    def violations(self) -> list[Violation]:
        """The constraint rows the last step violates (empty after a normal step)."""
        amounts = self._violation
        return [Violation(label, float(a)) for label, a in zip(self.assembled.row_labels, amounts) if a > 0]

    @property
    def backend(self) -> str:
        """'native' (generated C) or 'interpreted' (CasADi in this process)."""
        return self._step.kind

    @property
    def row_labels(self) -> list[RowLabel]:
        """Structured labels of the constraint rows (the rows of A after the variable bounds)."""
        return list(self.assembled.row_labels)

    # ------------------------------------------------------------------------------- checking
    def _prime(self) -> None:
        """One evaluation with phase 2 forced (input ``recover``) at the start configuration: every DAQP
        workspace of the generated step is allocated now, so that no later step allocates memory."""
        q_buf, u_buf, p_buf, dt_buf, recover = self._step.inputs
        q_buf[:] = self.task.start if self.task.start is not None else 0.0
        u_buf[:] = 0.0
        p_buf[:] = self._p_default
        dt_buf[...] = self.default_dt or 0.01
        recover[...] = 1.0
        try:
            self._step.evaluate()
        finally:
            recover[...] = 0.0

    def _all_labels(self) -> list[str]:
        bounds = []
        for i, joint_labels in enumerate(self.assembled.bound_labels):
            joint = self.assembled.context.robot.joint_names[i]
            bounds.append(f"bounds of joint {joint}: " + ("; ".join(map(str, joint_labels)) or "none"))
        bounds += [f"slack >= 0 of {label}" for label in self.assembled.slack_labels]
        return bounds + [str(label) for label in self.assembled.row_labels]

    def _write_unchecked(self, q, inputs, q_buf: np.ndarray, u_buf: np.ndarray) -> bool:
        """The fast path of :meth:`step`: write q and the inputs straight into the solver's buffers.
        False when anything is unusual (a name, a length, NaN or inf), for the detailed checks to report."""
        if type(inputs) is not dict or len(inputs) != len(self._input_offsets):
            return False
        try:
            if len(q) != self.nq:
                return False
            q_buf[:] = q
            for name, (offset, size) in self._input_offsets.items():
                value = inputs[name]
                if len(value) != size:
                    return False
                u_buf[offset:offset + size] = value
        except (KeyError, TypeError, ValueError):
            return False
        # A finite sum means every entry is finite; an overflow only sends the step to the detailed checks.
        return math.isfinite(q_buf.sum() + u_buf.sum())

    def _arguments(self, q, inputs, params, dt) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        q = _finite_vector(q, self.nq, "q (joint coordinates)")
        return q, self._inputs(inputs or {}), self._params(params or {}), self._dt(dt)

    def _inputs(self, inputs: dict) -> np.ndarray:
        if not isinstance(inputs, dict):
            raise VfError("inputs must be a mapping from input names to values")
        for name in inputs:
            if name not in self.input_sizes:
                raise VfError(f"unknown input '{name}'", hint=suggest(str(name), self.input_sizes, "inputs"))
        u = self._u
        for name, (offset, size) in self._input_offsets.items():
            if name not in inputs:
                raise VfError(f"missing input '{name}' ({size} numbers)",
                              hint="pass every declared input each tick, zeros when idle")
            u[offset:offset + size] = _finite_vector(inputs[name], size, f"input '{name}'")
        return u

    def _params(self, params: dict) -> np.ndarray:
        if not isinstance(params, dict):
            raise VfError("params must be a mapping from param names to values")
        p = self._p_default.copy() if params else self._p_default
        for name, value in params.items():
            slot = self._layout.slots.get(name)
            if slot is None or slot.size == 0:
                raise VfError(f"unknown run-time param '{name}'", hint=suggest(str(name), self.param_names, "params"))
            if isinstance(value, dict):
                value = _from_mapping(slot.type, value)
            if isinstance(value, BaseModel):
                value = flatten(value)
            p[slot.offset:slot.offset + slot.size] = _finite_vector(value, slot.size, f"param '{name}'")
        return p

    def _dt(self, dt) -> float:
        if dt is None:
            dt = self.default_dt
            if dt is None:
                raise VfError("no control period: pass dt, or set `period` in the task's scene")
        dt = float(dt)
        if not np.isfinite(dt) or dt <= 0:
            raise VfError(f"dt must be a positive number of seconds, got {dt}")
        return dt


def _finite_vector(value, size: int, what: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise VfError(f"{what} must be {size} numbers") from None
    if arr.size != size:
        raise VfError(f"{what} must have {size} numbers, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise VfError(f"{what} contains NaN or inf: {arr.tolist()}")
    return arr


_MAPPING_FIELDS = {"pose": ("translation", "rpy"), "line": ("point", "direction"), "plane": ("point", "normal")}


def _from_mapping(kind: str, value: dict) -> list[float]:
    fields = _MAPPING_FIELDS.get(kind)
    if fields is None or set(value) != set(fields):
        raise VfError(f"a {kind} param value is " + (f"a mapping with keys {', '.join(fields)}" if fields
                                                      else "a list of numbers"))
    return [x for f in fields for x in np.asarray(value[f], dtype=float).reshape(-1)]
