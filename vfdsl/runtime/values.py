"""Run-time values: what a caller hands to ``Controller.step``, checked before anything moves.

Every value is checked for its type (real numbers only: no strings, booleans, complex numbers or other
objects; lists, tuples and real NumPy arrays are fine), its shape, finiteness and the same ranges a
value written in the task file gets. Each failure is a :class:`~vfdsl.errors.VfError` that names the
argument (``q``, ``input 'tau'``, ``param 'axis'``, ``dt``). Everything is SI.

- q: within the joint limits widened by the joint's span on each side (a value further out is a
  faulty encoder or a unit mistake, e.g. degrees for radians, not a state to recover from);
- inputs: read here (types, shapes), then checked by their type's plausibility checks (:mod:`vfdsl.inputs`: every
  component finite);
- params: read here (types, shapes, finiteness), then checked by the task's column of margins
  (:mod:`vfdsl.compiler.admissible`: zero directions, implausible points, lengths and angles, scalar
  ranges, run-time curves, degenerate derived values), the same checks as at load time and in the generated C;
- dt: a positive number of seconds within the task's range around its period (:func:`dt_range`): a dt far from
  it is a unit slip (milliseconds given as seconds), not a late tick.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping

import casadi as ca
import numpy as np
from pydantic import BaseModel

from vfdsl.compiler.admissible import Admissible
from vfdsl.compiler.context import flatten
from vfdsl.errors import VfError, a_or_an, show_vector, suggest
from vfdsl.inputs import INPUT_TYPES
from vfdsl.inputs.base import FINITE
from vfdsl.ir import model as ir
from vfdsl.limits import MAX_PERIOD, MIN_PERIOD

DT_LONGER = 10
"""A dt may be up to this many times the task's period: the speed bounds scale with dt, so a dt K times the loop's
real period lets the joints reach K times their speed limits in that tick; 10 passes jitter and a late tick."""
DT_SHORTER = 100
"""A dt may be down to the period over this: a shorter dt only slows the motion (the speed bounds shrink with it, the
fixtures' rows do not depend on it), so the floor catches unit slips (x1000) and leaves room to run a task at a faster
loop (paper A's 40 ms scene simulated at 1 ms)."""
ASSUMED_PERIOD = 0.01
"""s: the period of a task without a scene period: dt is checked against it, and `check`, `simulate` and `view` run
at it."""
_FIELDS = {"line": ("point", "direction"), "plane": ("point", "normal"), "pose": ("translation", "rpy")}
JOINT_UNITS = {"revolute": "rad", "continuous": "rad", "prismatic": "m"}
INPUT_UNITS = {name: kind.unit_text for name, kind in INPUT_TYPES.items()}
PARAM_UNITS = {"point": "m", "vector": "m", "direction": "1 (normalized)", "line": "m (0-2), 1 (3-5)",
               "plane": "m (0-2), 1 (3-5)", "pose": "m (0-2), rad (3-5)", "curve": "m (x y z per point)",
               "length": "m", "angle": "rad", "speed": "m/s", "angular_speed": "rad/s", "number": "1", "time": "s",
               "force": "N"}
"""SI units of run-time values, by joint type, input type and param type (what a C caller passes)."""


def dt_range(period: float | None) -> tuple[float, float]:
    """The dt a task of scene period P accepts (s): [max(P / DT_SHORTER, MIN_PERIOD), min(P * DT_LONGER, MAX_PERIOD)],
    P = ASSUMED_PERIOD when the scene gives none. A scene period lies within [MIN_PERIOD, MAX_PERIOD] (checked at load),
    so its range holds it."""
    p = ASSUMED_PERIOD if period is None else period
    return max(p / DT_SHORTER, MIN_PERIOD), min(p * DT_LONGER, MAX_PERIOD)


def real_vector(value, size: int, what: str, finite: bool = True) -> np.ndarray:
    """``value`` as ``size`` float64 numbers, finite unless ``finite`` is False (the caller checks them): a list
    or tuple of real numbers, or a real NumPy array (1-D, or 2-D with one row or one column; 0-D for one number)."""
    if isinstance(value, np.ndarray):
        value = plain_array(value, what)
        if value.dtype.kind not in "fiu":
            raise VfError(f"{what} must be real numbers, got an array of {value.dtype}")
        if value.ndim > 2 or (value.ndim == 2 and 1 not in value.shape) or (value.ndim == 0 and size != 1):
            raise VfError(f"{what} must be a vector of {_count(size)}, got an array of shape {value.shape}")
        arr = value.astype(float).reshape(-1)
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            if not _is_real(item):
                raise VfError(f"{what} must be {size} real numbers; item {i} is {_describe(item)}")
        arr = np.array([_as_float(item, f"{what}'s item {i}", too_large=f"{what} holds a number too large for a float")
                        for i, item in enumerate(value)], dtype=float)
    else:
        raise VfError(f"{what} must have {_count(size)} (a list or array), got {_describe(value)}")
    if arr.size != size:
        raise VfError(f"{what} must have {_count(size)}, got {arr.size}")
    bad = np.flatnonzero(~np.isfinite(arr)) if finite else ()
    if len(bad):
        raise VfError(f"{what} contains NaN or inf (index {int(bad[0])}): {show_vector(arr)}")
    return arr


def real_scalar(value, what: str) -> float:
    """``value`` as a float: a real number, not a list, string or boolean (finiteness is the caller's
    range check; an int too large for a float is refused here, not read as inf)."""
    if not _is_real(value):
        raise VfError(f"{what} must be a real number, got {_describe(value)}")
    return _as_float(value, what, too_large=f"{what} is a number too large for a float")


def _as_float(x, what: str, too_large: str | None = None) -> float:
    """float(x) for a real number x; when too large for a float, VfError(too_large), or inf without it (the caller's
    range check refuses it); VfError when x's own conversion fails (a numbers.Real whose __float__ raises)."""
    try:
        return float(x)
    except OverflowError:
        if too_large:
            raise VfError(too_large) from None
        return math.inf
    except Exception as exc:  # noqa: BLE001 - any failure of a user type's __float__ is a bad value
        raise VfError(f"{what} cannot be read as a number ({type(exc).__name__}: {exc})") from None


def plain_array(value: np.ndarray, what: str) -> np.ndarray:
    """A NumPy array as a plain ndarray: a masked array's masked entries are missing values, refused (its data
    under the mask are no value the caller meant); any other subclass is viewed as an ndarray."""
    if np.ma.isMaskedArray(value):
        if np.ma.count_masked(value):
            raise VfError(f"{what} has masked (missing) entries", hint="pass every number, e.g. array.filled(...)")
        value = np.ma.getdata(value)
    return np.asarray(value)


def plain_mapping(value, what: str) -> dict:
    """A mapping as a dict (its items read once, here): VfError when a user mapping fails to give them."""
    try:
        return dict(value)
    except Exception as exc:  # noqa: BLE001 - any failure of a user mapping is a bad value
        raise VfError(f"{what} cannot be read as a mapping ({type(exc).__name__}: {exc})") from None


def _is_real(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _describe(x) -> str:
    if isinstance(x, str):
        return f"the string {x[:20]!r}"
    if isinstance(x, (bool, np.bool_)):
        return f"the boolean {x}"
    if isinstance(x, numbers.Complex) and not isinstance(x, numbers.Real):
        return f"the complex number {x}"
    return a_or_an(type(x).__name__)


def input_checks(types: Mapping, offsets: Mapping[str, tuple[int, int]], n: int) -> ca.Function:
    """u -> the column of the inputs' plausibility checks, compiled with the task as the params' column is: margin m is
    check m // n of component m % n of u (check-major; 1 where an input has fewer checks), and holds iff it is
    finite and >= 0 (:class:`vfdsl.inputs.base.InputCheck`). The Python path applies the same margins in NumPy
    (:meth:`RuntimeValues.inputs`), which also says which check failed."""
    u = ca.SX.sym("u", n)
    depth = max((len(kind.checks) for kind in types.values()), default=0)
    columns = []
    for j in range(depth):
        column = [ca.SX(1.0)] * n
        for name, (offset, size) in offsets.items():
            if j < len(types[name].checks):
                margin = types[name].checks[j].margin(u[offset:offset + size])
                column[offset:offset + size] = ca.vertsplit(margin)
        columns += column
    return ca.Function("input_checks", [u], [ca.vertcat(*columns) if columns else ca.SX(0, 1)], ["u"], ["margins"])


def admissible_joints(lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joint coordinates q accepts: its limits widened by their span on each side (farther out is a unit slip,
    degrees for radians, or a faulty encoder; an unbounded joint accepts any)."""
    span = np.where(np.isfinite(upper - lower), upper - lower, np.inf)
    return lower - span, upper + span


class RuntimeValues:
    """The checks of one task's run-time values (its inputs, params, joints and period)."""

    def __init__(self, task: ir.Task, input_offsets: dict[str, tuple[int, int]], admissible: Admissible,
                 lower: np.ndarray, upper: np.ndarray, joint_names: list[str]):
        self.task = task
        self.nq = len(lower)
        self.input_offsets = input_offsets
        self.n_inputs = sum(size for _, size in input_offsets.values())
        self.input_types = {d.name: INPUT_TYPES[d.type] for d in task.inputs}
        self.input_checks = input_checks(self.input_types, input_offsets, self.n_inputs)
        self.admissible = admissible
        self.layout = admissible.layout
        self.joint_names = joint_names
        self.lower, self.upper = lower, upper
        self.q_min, self.q_max = admissible_joints(lower, upper)
        self.default_period = task.scene.period
        self.dt_min, self.dt_max = dt_range(self.default_period)

    # ------------------------------------------------------------------------------------------ q
    def q(self, value) -> np.ndarray:
        q = real_vector(value, self.nq, "q (joint coordinates)")
        outside = np.flatnonzero((q < self.q_min) | (q > self.q_max))
        if outside.size:
            i = int(outside[0])
            raise VfError(f"q[{i}] = {q[i]:.6g} is far outside joint '{self.joint_names[i]}''s limits "
                          f"[{self.lower[i]:.6g}, {self.upper[i]:.6g}] (SI: m or rad)",
                          hint="check the unit (radians, metres) and the joint order, or the encoder")
        return q

    # ------------------------------------------------------------------------------------- inputs
    def inputs(self, value) -> np.ndarray:
        if value is None:
            value = {}
        if not isinstance(value, Mapping):
            raise VfError(f"inputs must be a mapping from input names to values, got {_describe(value)}")
        value = plain_mapping(value, "inputs")
        for name in value:
            if name not in self.input_offsets:
                raise VfError(f"unknown input {name!r}", hint=suggest(str(name), self.input_offsets, "inputs"))
        u = np.empty(self.n_inputs)
        for name, (offset, size) in self.input_offsets.items():
            if name not in value:
                raise VfError(f"missing input '{name}' ({_count(size)})",
                              hint="pass every declared input each tick, zeros when idle")
            x = real_vector(value[name], size, f"input '{name}'", finite=False)
            failed = self.input_types[name].first_failure(x)
            if failed:
                check, i = failed
                raise VfError(check.message(name, i, x))
            u[offset:offset + size] = x
        return u

    # ------------------------------------------------------------------------------------- params
    def params(self, value, margins=None) -> np.ndarray | None:
        """The full param vector with ``value``'s entries replaced, or None for the defaults. ``margins``:
        p -> the task's column of checks (default: evaluated by CasADi; a runner gives its generated C's)."""
        if value is None:
            return None
        if not isinstance(value, Mapping):
            raise VfError(f"params must be a mapping from param names to values, got {_describe(value)}")
        value = plain_mapping(value, "params")
        if not value:
            return None
        p = self.layout.defaults.copy()
        for name, given in value.items():
            slot = self.layout.slots.get(name)
            if slot is not None and slot.type == "mesh":
                frame = self.task.param(name).frame
                raise VfError(f"param {name!r} is a mesh: its file is read when the task is compiled",
                              hint=f"give another file in the scene file (params.{name}) and compile again"
                                   + (f"; at run time, move it with the pose it is in ({frame!r})" if frame else ""))
            if slot is None or slot.size == 0:
                known = [n for n, s in self.layout.slots.items() if s.size]
                raise VfError(f"unknown run-time param {name!r}", hint=suggest(str(name), known, "params"))
            p[slot.offset:slot.offset + slot.size] = self.param(name, slot.type, slot.size, given)
        self.admissible.verify(p, (margins or self.admissible.function)(p), f"with params {', '.join(map(repr, value))}, ")
        return p

    def param(self, name: str, kind: str, size: int, value) -> np.ndarray:
        what = f"param '{name}'"
        if kind == "curve":
            return self._curve(what, self.task.param(name).value, value)
        if isinstance(value, BaseModel):
            if getattr(value, "kind", None) != _ir_kind(kind):
                raise VfError(f"{what} is {a_or_an(kind)}, got {a_or_an(getattr(value, 'kind', '?'))} value")
            value = flatten(value)
        elif isinstance(value, Mapping):
            value = self._from_mapping(what, kind, plain_mapping(value, what))
        elif size == 1 and not isinstance(value, (list, tuple, np.ndarray)):
            value = [real_scalar(value, what)]          # a scalar param given as a number
        return real_vector(value, size, what)

    def _curve(self, what: str, default: ir.CurveValue, value) -> np.ndarray:
        """Run-time points of a ``runtime`` curve: N x 3 (a list of points, an array, or a curve value), read
        (their geometry is checked with the other params)."""
        n = len(default.points)
        if isinstance(value, ir.CurveValue):
            if value.degree != default.degree:
                raise VfError(f"{what} is a degree-{default.degree} curve, got a degree-{value.degree} one")
            value = value.points
        if isinstance(value, np.ndarray):
            value = plain_array(value, what)
        if isinstance(value, np.ndarray) and value.shape == (n, 3) and value.dtype.kind in "fiu":
            points = value.astype(float)
            bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
            if bad.size:
                real_vector(points[bad[0]], 3, f"{what}'s point {bad[0] + 1}")      # raises, naming the point
        elif isinstance(value, (list, tuple)) and len(value) == n:
            points = np.array([real_vector(point, 3, f"{what}'s point {i + 1}") for i, point in enumerate(value)])
        else:
            got = (f"{len(value)} points" if isinstance(value, (list, tuple)) else
                   f"an array of {value.dtype}, shape {value.shape}" if isinstance(value, np.ndarray) else _describe(value))
            raise VfError(f"{what} must be {n} points [x, y, z] (its declared count), got {got}",
                          hint="a run-time curve keeps the number of points of its default value")
        return points.reshape(-1)

    def _from_mapping(self, what: str, kind: str, value: Mapping) -> list:
        fields = _FIELDS.get(kind)
        if fields is None or set(value) != set(fields):
            raise VfError(f"{what} is {a_or_an(kind)}: " + (f"a mapping with keys {', '.join(fields)}" if fields
                                                              else "a list of numbers"))
        return [x for f in fields for x in real_vector(value[f], 3, f"{what}'s {f}")]

    # ----------------------------------------------------------------------------------------- dt
    def dt(self, value) -> float:
        if value is None:
            if self.default_period is None:
                raise VfError("no control period: pass dt, or set `period` in the task's scene")
            return self.default_period
        dt = real_scalar(value, "dt (the control period, s)")
        if not (dt > 0 and math.isfinite(dt)):
            raise VfError(f"dt must be a positive number of seconds, got {dt:.6g}",
                          hint="dt is the control period in seconds, e.g. 0.001 for a 1 kHz loop")
        if not self.dt_min <= dt <= self.dt_max:
            shown = f"{dt:.6g}"
            if self.dt_min <= float(shown) <= self.dt_max:     # just outside: rounded, it would look inside
                shown = repr(dt)
            raise VfError(f"dt = {shown} s {self.dt_rule}",
                          hint="dt is in seconds (1 ms is 0.001): pass the loop's period; if the loop really runs at "
                               "that period, give it as the `period` of the task's scene")
        return dt

    @property
    def input_rule(self) -> str:
        """What an input its checks refuse is told by the C library (VF_ERR_INPUT): finite, and each input's
        further checks (a button's range, a pose's plausible position and angles)."""
        rules = [f"'{name}' ({kind.name}): {check.meaning}" for name, kind in self.input_types.items()
                 for check in kind.checks if check is not FINITE]
        checks = "" if not rules else ", or fails its type's check: " + "; ".join(rules)
        return "an input contains NaN or inf" + checks

    @property
    def dt_rule(self) -> str:
        """What a dt outside [dt_min, dt_max] is told (also the C library's message, after "dt")."""
        period = (f"{_time(self.default_period)}, its scene's `period`" if self.default_period is not None
                  else f"none in its scene: {_time(ASSUMED_PERIOD)} assumed")
        return (f"is far from the task's period ({period}): it must be within "
                f"[{_time(self.dt_min)}, {_time(self.dt_max)}]")


def _time(seconds: float) -> str:
    return f"{seconds:g} s" if seconds >= 1 else f"{seconds * 1e3:g} ms"


def _ir_kind(kind: str) -> str:
    return "scalar" if kind not in ("point", "vector", "direction", "line", "plane", "pose", "curve") else kind


def _count(size: int) -> str:
    """'1 number', '3 numbers'."""
    return f"{size} number" + ("s" if size != 1 else "")
