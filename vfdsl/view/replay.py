"""Reading a per-tick trace (CSV, or the MCAP of ``vfdsl simulate --trace run.mcap``: :func:`read_mcap`) for
``vfdsl view TASK --replay FILE``.

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
  deg by a ``_mm`` / ``_deg`` suffix; used when there are exactly as many as the param has numbers;
- a procedure's (optional): ``phase`` (the phase's name at the tick) and ``monitor.<name>`` (1 when the monitor
  held, else 0), as ``vfdsl simulate`` writes them.

Empty cells are missing values (and so is an error or status that is not finite); rows without a time or
with a missing joint are dropped. The file is a regular file of UTF-8 text of at most
``limits.TRACE_BYTES``; anything else is a VfError.
"""

from __future__ import annotations

import csv
import math
import os
import re
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vfdsl import limits
from vfdsl.errors import VfError
from vfdsl.files import open_file

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
    phase: np.ndarray | None = None  # N phase names (str; "" where the cell is empty)
    monitors: dict[str, np.ndarray] = field(default_factory=dict)  # name -> N values (1 held, 0 not, NaN missing)

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


def read(path: str | Path, joint_names: list[str], period: float | None = None, trial: str | None = None,
         params: dict[str, int] | None = None) -> Trace:
    """The trace in ``path`` for a robot with joints ``joint_names`` (see the module's docstring); ``params``:
    the run-time params to read (name -> number of values). The file is read row by row, keeping only the
    numbers of the columns used."""
    path = Path(path)
    if path.suffix.lower() == ".mcap":
        return read_mcap(path, joint_names, trial, params or {})
    if path.suffix.lower() == ".parquet":
        raise VfError(f"{path}: a trace to replay is a CSV file, not Parquet",
                      hint="write the run's trace as CSV: vfdsl simulate TASK --trace run.csv")
    fd = open_file(path, "trace", limit=limits.TRACE_BYTES)
    try:
        with open(fd, encoding="utf-8-sig", newline="") as handle:
            return _parse(path, csv.reader(handle), joint_names, period, trial, params or {})
    except UnicodeDecodeError:
        raise VfError(f"{path}: not a text file (it holds bytes that are not UTF-8)",
                      hint="a trace is a CSV file with a header row and one row per tick") from None
    except csv.Error as err:
        raise VfError(f"{path}: not a CSV file ({err})",
                      hint="a trace is a CSV file with a header row and one row per tick") from None
    except OSError as err:
        raise VfError(f"cannot read the trace {path}: {err.strerror or err}") from None


def read_mcap(path: Path, joint_names: list[str], trial: str | None = None, params: dict[str, int] | None = None) -> Trace:
    """An MCAP trace as ``vfdsl simulate --trace run.mcap`` writes it (vfdsl.sim.mcap_trace): the joints from
    /joint_states (by name), the status, the first metric whose name holds ``error``, a procedure's phase, each
    run-time param of ``params`` (name -> size) from /vfdsl/param/<name> as the CSV's param columns; a run of several
    trials keeps trial ``trial`` (its /trial_<k> topics; default the first). Messages are matched by stamp; each
    joint state is read by its own names, and one holding NaN is dropped (as a CSV row with a missing joint)."""
    from rosbags.highlevel import AnyReader
    os.close(open_file(path, "trace", limit=limits.TRACE_BYTES))        # a regular file within the size limit
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as exc:                     # rosbags' errors: not an MCAP file, a damaged one
        raise VfError(f"{path}: not a readable MCAP trace ({exc})",
                      hint="write one with vfdsl simulate TASK --trace run.mcap") from None
    try:
        topics = {c.topic: c for c in reader.connections}
        prefixes = sorted({t[:-len("/joint_states")] for t in topics if t.endswith("/joint_states")})
        if not prefixes:
            raise VfError(f"{path}: no /joint_states topic: not a trace vfdsl simulate wrote",
                          hint="its topics: " + ", ".join(sorted(topics)))
        prefix = prefixes[0] if trial is None else f"/trial_{trial}"
        if prefix not in prefixes:
            raise VfError(f"{path}: no trial {trial}", hint="its trials: " + ", ".join(p[len('/trial_'):] for p in prefixes))

        def read(topic):
            connection = topics.get(prefix + topic)
            if connection is None:
                return {}
            return {stamp: reader.deserialize(raw, connection.msgtype)
                    for _, stamp, raw in reader.messages(connections=[connection])}
        states = read("/joint_states")
        if not states:
            raise VfError(f"{path}: its {prefix}/joint_states topic has no message")
        origin = min(states)
        order = sorted(states)
        stamps = np.array(order)
        q = np.array([_positions(path, k, states[s], joint_names) for k, s in enumerate(order)])
        finite = np.all(np.isfinite(q), axis=1)           # as the CSV: a NaN joint drops its row
        if not finite.any():
            raise VfError(f"{path}: no joint state with every joint finite")
        stamps, q = stamps[finite], q[finite]
        status = read("/vfdsl/status")
        metrics = sorted(t[len(prefix) + len("/vfdsl/metric/"):] for t in topics
                         if t.startswith(prefix + "/vfdsl/metric/") and "error" in t)
        error = read(f"/vfdsl/metric/{metrics[0]}") if metrics else {}
        phase = read("/vfdsl/phase")
        moved = {name: read(f"/vfdsl/param/{name}") for name in (params or {})}
    except VfError:
        raise
    except Exception as exc:                     # a damaged chunk or message past the summary rosbags opened
        raise VfError(f"{path}: not a readable MCAP trace ({exc})") from None
    finally:
        reader.close()

    def column(messages, value, missing):
        return np.array([value(messages[s]) if s in messages else missing for s in stamps])
    return Trace(t=(stamps - origin) * 1e-9, q=q,
                 error=column(error, lambda m: m.data, math.nan) if error else None,
                 error_name=f"metric.{metrics[0]}" if metrics else None,
                 status=column(status, lambda m: float(m.data), math.nan) if status else None,
                 trial=None if trial is None and len(prefixes) == 1 else prefix[len("/trial_"):],
                 columns=tuple(sorted(topics)),
                 phase=column(phase, lambda m: m.data, "") if phase else None,
                 params={name: np.array([np.asarray(messages[s].data, dtype=float) for s in stamps])
                         for name, messages in moved.items()
                         if messages and all(s in messages and len(messages[s].data) == params[name] for s in stamps)})


def _positions(path: Path, index: int, message, joint_names: list[str]) -> np.ndarray:
    """The positions of ``joint_names`` in JointState ``index`` of a trace, by that message's own names."""
    names, position = list(message.name), np.asarray(message.position, dtype=float)
    missing = [j for j in joint_names if j not in names]
    if missing:
        raise VfError(f"{path}: joint state {index} has no joint '{missing[0]}' of the task's robot")
    if len(position) != len(names):
        raise VfError(f"{path}: joint state {index} names {len(names)} joints but has {len(position)} positions")
    return position[[names.index(j) for j in joint_names]]


def _parse(path: Path, reader, joint_names: list[str], period: float | None, trial: str | None,
           params: dict[str, int]) -> Trace:
    header = next(reader, None)
    if header is None:
        raise VfError(f"{path}: no rows (a trace is a CSV file with a header row and one row per tick)")
    header = [h.strip() for h in header]
    lower = [h.lower() for h in header]
    trial_col = lower.index("trial") if "trial" in lower else None
    if trial is not None and trial_col is None:
        raise VfError(f"{path}: no trial column, so no trial {trial!r} to pick",
                      hint="leave --trial out: the trace holds one run")
    time_col = next((lower.index(n) for n in TIME_NAMES if n in lower), None)
    if time_col is not None:
        columns = [(time_col, 1.0)]
    elif "tick" in lower and period:
        columns = [(lower.index("tick"), period)]
    else:
        raise VfError(f"{path}: no time column", hint=f"name one of {', '.join(TIME_NAMES)} (seconds), or "
                      "give a 'tick' column and a scene period")
    for i, name in enumerate(joint_names):
        found = joint_column(header, i, name)
        if found is None:
            raise VfError(f"{path}: no column for joint {i} ({name})",
                          hint=f"name it q[{i}], q_{name} or q.{name}_<unit>; columns: {', '.join(header[:12])}"
                               + (" ..." if len(header) > 12 else ""))
        columns.append((header.index(found[0]), found[1]))
    error_name = _error_column(header)
    if error_name is not None:
        suffix = error_name.rsplit("_", 1)[-1].lower() if "_" in error_name else ""
        columns.append((header.index(error_name), _SCALE.get(suffix, 1.0)))
    if "status" in lower:
        columns.append((lower.index("status"), 1.0))
    read_params = {}
    for name, size in params.items():
        found = [k for k, c in enumerate(header) if c.startswith(f"param.{name}.")]
        if len(found) == size:
            read_params[name] = len(columns)
            columns += [(k, _SCALE.get(header[k].rsplit("_", 1)[-1].lower(), 1.0) if "_" in header[k] else 1.0)
                        for k in found]
    monitors = {}
    for k, c in enumerate(header):
        if c.startswith("monitor.") and len(c) > len("monitor."):
            monitors[c[len("monitor."):]] = len(columns)
            columns.append((k, 1.0))
    phase_col = lower.index("phase") if "phase" in lower else None
    values, trials, phases, names = array("d"), {}, array("l"), {}
    for r in reader:
        if trial_col is not None:
            if len(r) <= trial_col:
                continue
            if len(trials) <= 20:
                trials.setdefault(r[trial_col], None)
            if trial is None:
                trial = r[trial_col]
            if r[trial_col] != trial:
                continue
        values.extend(_number(r[k]) * f if len(r) > k else math.nan for k, f in columns)
        if phase_col is not None:
            phases.append(names.setdefault(r[phase_col].strip() if len(r) > phase_col else "", len(names)))
    if not values and not trials:
        raise VfError(f"{path}: no rows (a trace is a CSV file with a header row and one row per tick)")
    if not values:
        raise VfError(f"{path}: no trial {trial!r}", hint=f"trials in the file: {', '.join(list(trials)[:20])}")
    data = np.frombuffer(values, dtype=float).reshape(-1, len(columns))
    nq = len(joint_names)
    t, q = data[:, 0], data[:, 1:1 + nq]
    k = 1 + nq
    error = status = None
    if error_name is not None:
        error, k = data[:, k], k + 1
    if "status" in lower:
        status = data[:, k]
    keep = np.isfinite(t) & np.all(np.isfinite(q), axis=1)
    backwards = np.flatnonzero(np.diff(t[keep]) < 0)
    if backwards.size:                                    # another run follows: keep the first
        last = np.flatnonzero(keep)[backwards[0]]
        keep[last + 1:] = False
    if not keep.any():
        raise VfError(f"{path}: no row with a time and every joint")
    return Trace(t=t[keep], q=q[keep], error=None if error is None else _finite_or_nan(error[keep]),
                 error_name=error_name, status=None if status is None else _finite_or_nan(status[keep]),
                 trial=trial, columns=tuple(header),
                 params={name: data[keep, k:k + params[name]] for name, k in read_params.items()},
                 phase=_phases(phases, names, keep), monitors={name: data[keep, k] for name, k in monitors.items()})


def _phases(codes: array, names: dict[str, int], keep: np.ndarray) -> np.ndarray | None:
    """The phase column's names at the kept rows; None without a column or with every cell empty."""
    if not codes or set(names) <= {""}:
        return None
    table = np.array(sorted(names, key=names.get), dtype=object)
    return table[np.array(codes, dtype=np.int64)[keep]]


def _finite_or_nan(x: np.ndarray) -> np.ndarray:
    """Missing (NaN) where a value is not finite: an infinite error would scale the trace's colours to nothing."""
    return np.where(np.isfinite(x), x, math.nan)
