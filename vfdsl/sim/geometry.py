"""Reference geometry for scoring a run, computed here in numpy and scipy, apart from the compiler.

A param expressed in a pose param (``param path : curve in plate``) is mapped to the world by that pose:
p_world = R(rpy) p + t, with R the fixed-axis roll-pitch-yaw rotation (URDF convention, scipy's "xyz").
A curve is the b-spline of its degree interpolating its points with the cumulative chord length as
parameter (the definition of a ``curve`` value); its closest point to x is found by a dense search over
samples followed by Newton steps on (C(s) - x) . C'(s) = 0; on a polyline (degree 1) by projecting x on
every segment (the later segment on a tie). The distance is to the curve itself, ends included: a point
past an end is as far from the curve as from the end point (the paper's "distance to the curve"; the
``follows`` constraint continues the curve by its end tangents, and a frame pushed along that continuation
is off the curve by the distance it went). A derived argument
(``line(entry, target)``) is computed from the params' current values by :mod:`vfdsl.compiler.derived`: its
few vector operations are the definition of the value, not a model of the robot.

A scene's motions (:class:`~vfdsl.sim.settings.Motion`) displace run-time params tick by tick; a
:class:`Scene` carries those displacements and adds them in every accessor, so each tick is scored against
the geometry in force at that tick (a moved curve by searching the unmoved one for x - d; a derived argument
by its definition evaluated on the moved params).
"""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from vfdsl.compiler import derived
from vfdsl.compiler.context import ParamLayout, ParamReader, flatten
from vfdsl.ir import model as ir

SAMPLES_PER_METRE = 20000            # dense-search samples: 0.05 mm apart
NEWTON_STEPS = 8


def unit(v) -> np.ndarray:
    """v normalized (each row of an N x 3 array)."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def pose_matrix(pose: ir.PoseValue) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of a pose value: p_world = R p + t."""
    return Rotation.from_euler("xyz", pose.rpy).as_matrix(), np.asarray(pose.translation, dtype=float)


class Curve:
    """A ``curve`` value as a scipy b-spline, in its own coordinates (the frame it is expressed in)."""

    def __init__(self, value: ir.CurveValue, shift=(0.0, 0.0, 0.0)):
        from scipy.interpolate import make_interp_spline   # here: ~0.5 s to import, and most tasks have no curve

        points = np.asarray(value.points, dtype=float) + np.asarray(shift, dtype=float)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        self.length = float(s[-1])
        self.spline = make_interp_spline(s, points, k=value.degree)
        self._d1 = self.spline.derivative(1)
        self._d2 = self.spline.derivative(2) if value.degree > 1 else None
        self._breaks, self._corners = s, points
        self._grid = np.linspace(0.0, self.length, max(2001, int(self.length * SAMPLES_PER_METRE)))
        self._samples = self.spline(self._grid)
        self._squares = np.sum(self._samples ** 2, axis=1)

    def closest(self, x: np.ndarray, refine: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """For points x (N x 3): the parameter s of the closest curve point (0 <= s <= length), and the
        distance to it; ``refine=False``: the nearest sample, 0.05 mm apart, and the distance to it."""
        x = np.atleast_2d(x)
        if self._d2 is None:
            return self._closest_on_segments(x, refine)
        t = np.concatenate([self._grid[np.argmin(self._squares[None, :] - 2 * chunk @ self._samples.T, axis=1)]
                            for chunk in np.array_split(x, max(1, len(x) // 256))])
        for _ in range(NEWTON_STEPS if refine else 0):
            r = self.spline(t) - x
            f = np.sum(r * self._d1(t), axis=1)
            df = np.sum(self._d1(t) ** 2, axis=1) + np.sum(r * self._d2(t), axis=1)
            t = np.clip(t - f / np.where(df > 0, df, np.inf), 0.0, self.length)
        return t, np.linalg.norm(x - self.spline(t), axis=1)

    def _closest_on_segments(self, x: np.ndarray, refine: bool) -> tuple[np.ndarray, np.ndarray]:
        """A polyline's exact closest points: x projected on every segment, the later segment on a tie."""
        a, b = self._corners[:-1], self._corners[1:]
        lengths = np.diff(self._breaks)
        d = (b - a) / lengths[:, None]
        t = np.clip(np.einsum("nsk,sk->ns", x[:, None, :] - a[None], d), 0.0, lengths)      # N x S
        distance = np.linalg.norm(x[:, None, :] - a[None] - t[..., None] * d[None], axis=2)
        k = len(lengths) - 1 - np.argmin(distance[:, ::-1], axis=1)
        t = self._breaks[k] + t[np.arange(len(x)), k]
        return t, np.linalg.norm(x - self.spline(t), axis=1)

    def tangent(self, s: float) -> np.ndarray:
        return unit(self._d1(s))


class Scene:
    """The task's params as the world sees them: their values (a disturbance may move a pose or point
    param) and, for the params a scene's motions move, their displacements (:class:`~vfdsl.sim.settings.Motion`),
    in each param's own coordinates: one row (3 numbers, or 1 for a scalar) in a running trial's live scene,
    N rows when a segment of N ticks is scored. Every accessor adds them, so where a param moves its geometry
    has a leading axis of N samples (and broadcasts against N frame poses), and where none moves it is one
    value."""

    def __init__(self, task: ir.Task):
        self.task = task
        self.values: dict[str, ir.Value] = {p.name: p.value for p in task.params}
        self.shifts: dict[str, np.ndarray] = {}
        self._frames = {p.name: p.frame for p in task.params}
        self._poses: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def with_values(self, values: dict[str, ir.Value], shifts: dict[str, np.ndarray] | None = None) -> "Scene":
        """The same task's params with other values (a snapshot taken before or after a disturbance), and
        the displacements of the moving ones (rows of ticks)."""
        scene = Scene(self.task)
        scene.values = dict(values)
        scene.shifts = dict(shifts or {})
        return scene

    def moved(self, name: str, translate, tilt) -> ir.Value:
        """Move a pose param (translate, then turn it about its origin by the rotation vector ``tilt``, both
        in world axes) or translate a point param; returns its new value."""
        value = self.values[name]
        if isinstance(value, ir.PoseValue):
            R = Rotation.from_rotvec(tilt) * Rotation.from_euler("xyz", value.rpy)
            value = ir.PoseValue(translation=list(np.add(value.translation, translate)),
                                 rpy=list(R.as_euler("xyz")))
        else:
            value = ir.PointValue(xyz=list(np.add(value.xyz, translate)))
        self.values[name] = value
        self._poses.pop(name, None)
        return value

    def set_value(self, name: str, value: ir.Value) -> None:
        """Give param ``name`` another value (what is expressed in a pose param moves with it)."""
        self.values[name] = value
        self._poses.clear()

    def shift(self, arg: ir.Arg | None):
        """The displacement of a param argument (0 when it does not move): 3 numbers or N x 3 in its own
        coordinates; 1 number or N x 1 for a scalar."""
        if isinstance(arg, ir.ParamRef):
            return self.shifts.get(arg.name, 0.0)
        return 0.0

    def to_world(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(R, t) mapping param ``name``'s own coordinates to the world (identity for a world param): x_world
        = x @ R.T + t, t N x 3 where the pose moves."""
        frame = self._frames.get(name)
        if frame is None:
            return np.eye(3), np.zeros(3)
        if frame not in self._poses:
            self._poses[frame] = pose_matrix(self.values[frame])
        R, t = self._poses[frame]
        return R, t + self.shifts.get(frame, 0.0)

    def local(self, arg: ir.Arg, x: np.ndarray) -> np.ndarray:
        """World points x in the coordinates of the (undisplaced) value of ``arg``: a curve's closest point
        to x moved by d is the unmoved curve's closest point to x - d."""
        if not isinstance(arg, ir.ParamRef):
            return x
        R, t = self.to_world(arg.name)
        return (x - t) @ R - self.shift(arg)

    def point(self, arg: ir.Arg) -> np.ndarray:
        value, (R, t) = self._resolve(arg)
        return (np.asarray(value.xyz, dtype=float) + self.shift(arg)) @ R.T + t

    def direction(self, arg: ir.Arg) -> np.ndarray:
        value, (R, _) = self._resolve(arg)
        return unit(np.asarray(value.xyz, dtype=float) @ R.T)

    def line(self, arg: ir.Arg) -> tuple[np.ndarray, np.ndarray]:
        value, (R, t) = self._resolve(arg)
        return (np.asarray(value.point) + self.shift(arg)) @ R.T + t, unit(np.asarray(value.direction) @ R.T)

    def plane(self, arg: ir.Arg) -> tuple[np.ndarray, np.ndarray]:
        """(point, unit normal toward the free side)."""
        value, (R, t) = self._resolve(arg)
        return (np.asarray(value.point) + self.shift(arg)) @ R.T + t, unit(np.asarray(value.normal) @ R.T)

    def scalar(self, arg: ir.Arg):
        """A scalar argument's value: a number, or N numbers where a motion changes it."""
        shift = self.shift(arg)
        return self.value(arg).value + (shift[..., 0] if np.ndim(shift) else shift)

    def value(self, arg: ir.Arg) -> ir.Value:
        """The value of an argument as written (without its displacement)."""
        return self._resolve(arg)[0]

    def _resolve(self, arg: ir.Arg) -> tuple[ir.Value, tuple[np.ndarray, np.ndarray]]:
        if isinstance(arg, ir.ParamRef):
            return self.values[arg.name], self.to_world(arg.name)
        if isinstance(arg, ir.Const):
            return arg.value, (np.eye(3), np.zeros(3))
        if isinstance(arg, ir.Derived):           # computed in the world from the params' current values
            if self.shifts:
                return self._derived_rows(arg), (np.eye(3), np.zeros(3))
            p = ca.DM(np.concatenate([[], *(flatten(self.values[d.name]) for d in self.task.params)]))
            return derived.to_value(arg.kind, ParamReader(self.task.params, p).derived(arg)), (np.eye(3), np.zeros(3))
        raise TypeError(f"not a value argument: {arg}")

    def _derived_rows(self, arg: ir.Derived) -> SimpleNamespace:
        """A derived argument at every row of the displacements: its definition (a CasADi function of the flat
        params, built once) evaluated on the params' values plus their displacements, all rows in one call."""
        layout = ParamLayout(self.task.params)
        rows = max((len(s) for s in self.shifts.values() if np.ndim(s) == 2), default=0)
        P = np.tile(np.concatenate([[], *(flatten(self.values[d.name]) for d in self.task.params)]), (max(rows, 1), 1))
        for name, shift in self.shifts.items():
            slot = layout.slots[name]
            shift = np.atleast_2d(shift)
            if slot.type == "curve":
                P[:, slot.offset:slot.offset + slot.size] += np.tile(shift, slot.size // 3)
            else:
                P[:, slot.offset:slot.offset + shift.shape[1]] += shift
        outputs = _derived_function(self.task, arg).map(len(P))(P.T)
        parts = [np.array(x).T for x in (outputs if isinstance(outputs, (list, tuple)) else [outputs])]
        if not rows:
            parts = [x[0] for x in parts]
        fields = {"line": ("point", "direction"), "plane": ("point", "normal")}.get(arg.kind, ("xyz",))
        return SimpleNamespace(**dict(zip(fields, parts)))


_FUNCTIONS: dict = {}


def _derived_function(task: ir.Task, arg: ir.Derived) -> ca.Function:
    """p (the flat run-time params) -> the value of a derived argument (a point, or a line's point and unit)."""
    key = (tuple((d.name, d.type, len(flatten(d.value))) for d in task.params), arg.model_dump_json())
    if key not in _FUNCTIONS:
        p = ca.SX.sym("p", ParamLayout(task.params).size)
        value = ParamReader(task.params, p).derived(arg)
        _FUNCTIONS[key] = ca.Function("derived", [p], list(value) if isinstance(value, tuple) else [value])
    return _FUNCTIONS[key]
