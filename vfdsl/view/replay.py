"""Reading a per-tick trace (CSV) for ``vfdsl view TASK --replay FILE``.

Accepted format: a CSV file with a header row, one row per tick (extra columns are ignored):

- time: the first column named ``t``, ``time``, ``t_s`` or ``time_s`` (seconds); without one, ``tick``
  times the task's period;
- joints: one column per joint of the task's robot, named by its index or its name, with or without a
  unit suffix: ``q[0]``, ``q_0``, ``q0``, ``q.0``, ``q[x]``, ``q_x``, ``q.x``, ``q.x_m``, ``q.rcm_a_rad``;
  a suffix ``_mm`` or ``_deg`` converts from mm or degrees, anything else is SI (m, rad);
- trial (optional): where a ``trial`` column holds several trials, one is replayed (``--trial``, default the
  first); rows whose time goes backwards start another run (grid points), and only the first is kept;
- error (optional): the first column whose name contains ``error`` (those starting with ``metric.`` first,
  ``tracker.`` columns last), in m (or mm / deg / rad by its suffix); it colours the tool's trace;
- status (optional): the step status flags (0 optimal, 1 least violation, 2 bounds clipped, 4 fallback);
- params (optional): a run-time param's value at each tick, as the columns starting ``param.<name>.`` in
  the order of its flat value (point x y z; direction x y z; line point then direction; plane point then
  normal; pose x y z roll pitch yaw; a run-time curve's points one after the other; a scalar), SI, or mm /
  deg by a ``_mm`` / ``_deg`` suffix; used when there are exactly as many as the param has numbers.

Empty cells are missing values; rows without a time or with a missing joint are dropped.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vfdsl.errors import VfError

TIME_NAMES = ("t", "time", "t_s", "time_s")
_SCALE = {"mm": 1e-3, "deg": math.pi / 180}


@dataclass
class Trace:
    t: np.ndarray                    # N times (s)
    q: np.ndarray                    # N x nq joint coordinates (SI)
    error: np.ndarray | None = None  # N values (SI), NaN where missing
    error_name: str | None = None
    status: np.ndarray | None = None
    trial: str | None = None
    columns: tuple[str, ...] = ()
    params: dict[str, np.ndarray] = field(default_factory=dict)   # name -> N x size (SI)

    def index_at(self, t: float) -> int:
        """The row at or just before time t."""
        return int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1))


def joint_column(header: list[str], index: int, name: str) -> tuple[str, float] | None:
    """The column of joint ``index`` (named ``name``) and the factor to SI, or None."""
    for key in ([re.escape(name)] if name else []) + [str(index)]:
        pattern = re.compile(rf"^q(?:\[{key}\]|[._]?{key})(?:_(m|rad|mm|deg))?$", re.IGNORECASE)
        for column in header:
            match = pattern.match(column.strip())
            if match:
                return column, _SCALE.get((match.group(1) or "").lower(), 1.0)
    return None


def _error_column(header: list[str]) -> str | None:
    candidates = [c for c in header if "error" in c.lower()]
    if not candidates:
        return None
    rank = lambda c: (0 if c.lower().startswith("metric.") else 2 if c.lower().startswith("tracker.") else 1)
    return sorted(candidates, key=lambda c: (rank(c), header.index(c)))[0]


def _number(cell: str) -> float:
    try:
        return float(cell) if cell.strip() else math.nan
    except ValueError:
        return math.nan


def unflatten(old, flat):
    """A param value of the same kind as ``old`` (an IR value) from the numbers of its flat run-time value."""
    from vfdsl.ir import model as ir
    v = [float(x) for x in flat]
    if isinstance(old, (ir.PointValue, ir.VectorValue, ir.DirectionValue)):
        return type(old)(xyz=v)
    if isinstance(old, ir.LineValue):
        return ir.LineValue(point=v[:3], direction=v[3:])
    if isinstance(old, ir.PlaneValue):
        return ir.PlaneValue(point=v[:3], normal=v[3:])
    if isinstance(old, ir.PoseValue):
        return ir.PoseValue(translation=v[:3], rpy=v[3:])
    if isinstance(old, ir.CurveValue):
        return ir.CurveValue(degree=old.degree, points=[v[i:i + 3] for i in range(0, len(v), 3)], runtime=True)
    if isinstance(old, ir.ScalarValue):
        return ir.ScalarValue(dimension=old.dimension, value=v[0])
    return old


def read(path: str | Path, joint_names: list[str], period: float | None = None, trial: str | None = None,
         params: dict[str, int] | None = None) -> Trace:
    """The trace in ``path`` for a robot with joints ``joint_names`` (see the module's docstring); ``params``:
    the run-time params to read (name -> number of values)."""
    path = Path(path)
    try:
        with path.open(newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as err:
        raise VfError(f"cannot read the trace {path}: {err.strerror or err}") from None
    if len(rows) < 2:
        raise VfError(f"{path}: no rows (a trace is a CSV file with a header row and one row per tick)")
    header = [h.strip() for h in rows[0]]
    lower = [h.lower() for h in header]
    data = rows[1:]
    if "trial" in lower:
        k = lower.index("trial")
        trials = list(dict.fromkeys(r[k] for r in data if len(r) > k))
        if trial is None:
            trial = trials[0]
        elif trial not in trials:
            raise VfError(f"{path}: no trial {trial!r}", hint=f"trials in the file: {', '.join(trials[:20])}")
        data = [r for r in data if len(r) > k and r[k] == trial]
    time_col = next((lower.index(n) for n in TIME_NAMES if n in lower), None)
    if time_col is not None:
        t = np.array([_number(r[time_col]) if len(r) > time_col else math.nan for r in data])
    elif "tick" in lower and period:
        k = lower.index("tick")
        t = np.array([_number(r[k]) * period if len(r) > k else math.nan for r in data])
    else:
        raise VfError(f"{path}: no time column", hint=f"name one of {', '.join(TIME_NAMES)} (seconds), or "
                      "give a 'tick' column and a scene period")
    q = np.empty((len(data), len(joint_names)))
    for i, name in enumerate(joint_names):
        found = joint_column(header, i, name)
        if found is None:
            raise VfError(f"{path}: no column for joint {i} ({name})",
                          hint=f"name it q[{i}], q_{name} or q.{name}_<unit>; columns: {', '.join(header[:12])}"
                               + (" ..." if len(header) > 12 else ""))
        column, scale = found
        k = header.index(column)
        q[:, i] = [_number(r[k]) * scale if len(r) > k else math.nan for r in data]
    error_name = _error_column(header)
    error = None
    if error_name is not None:
        k = header.index(error_name)
        suffix = error_name.rsplit("_", 1)[-1].lower() if "_" in error_name else ""
        error = np.array([_number(r[k]) if len(r) > k else math.nan for r in data]) * _SCALE.get(suffix, 1.0)
    status = None
    if "status" in lower:
        k = lower.index("status")
        status = np.array([_number(r[k]) if len(r) > k else math.nan for r in data])
    values = {}
    for name, size in (params or {}).items():
        found = [k for k, c in enumerate(header) if c.startswith(f"param.{name}.")]
        if len(found) == size:
            scale = [_SCALE.get(header[k].rsplit("_", 1)[-1].lower(), 1.0) if "_" in header[k] else 1.0
                     for k in found]
            values[name] = np.array([[_number(r[k]) * f if len(r) > k else math.nan for k, f in zip(found, scale)]
                                     for r in data]).reshape(len(data), size)
    keep = np.isfinite(t) & np.all(np.isfinite(q), axis=1)
    backwards = np.flatnonzero(np.diff(t[keep]) < 0)
    if backwards.size:                                    # another run follows: keep the first
        last = np.flatnonzero(keep)[backwards[0]]
        keep[last + 1:] = False
    if not keep.any():
        raise VfError(f"{path}: no row with a time and every joint")
    return Trace(t=t[keep], q=q[keep], error=None if error is None else error[keep], error_name=error_name,
                 status=None if status is None else status[keep], trial=trial, columns=tuple(header),
                 params={name: v[keep] for name, v in values.items()})
