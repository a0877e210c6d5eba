"""The per-tick trace of a run: one row per tick per trial, every value in SI units, as CSV or Parquet (or as an
MCAP file of ROS 2 messages: :mod:`vfdsl.sim.mcap_trace`).

Columns, in this order (``<unit>`` is the SI unit as a suffix: ``m``, ``rad``, ``s``, ``N``, ``Nm``, ``m_s``
for m/s, ``rad_s`` for rad/s; a dimensionless number has no suffix)::

    trial, seed                    the trial's index in its grid point and its seed
    <setting>                      grid runs only: the grid point's settings (period_s, latency_s, ...)
    tick, t_s                      tick k and its time k * period
    q.<joint>_<m|rad>              the encoder reading the controller was given at this tick
    dq.<joint>_<m|rad>             the increment it commanded
    input.<input>.<axis>_<unit>    every declared input at this tick (the hand's force, torque or twist):
                                   force fx fy fz (N), torque tx ty tz (Nm), wrench both, twist vx vy vz
                                   (m/s) and wx wy wz (rad/s)
    param.<param>.<part>_<unit>    every run-time param as the controller had it at this tick, moved by
                                   the scene's motions and disturbances: point / vector x y z (m),
                                   direction x y z, line px py pz (m) dx dy dz, plane px py pz (m) nx ny nz,
                                   pose x y z (m) roll pitch yaw (rad, fixed-axis xyz), a run-time curve
                                   p<i>.x p<i>.y p<i>.z (m) per point, a scalar its own unit
    status                         the step's status flags: 0 optimal, +1 least violation, +2 joint bounds
                                   clipped, +4 fallback (zero motion), +8 priority levels not certified
                                   exact
    violations                     what the step left violated, ``"label: amount unit"`` joined by ``"; "``
                                   (a hard row's excess, a soft constraint's slack); empty when none
    metric.<name>_<unit>           every metric of the run at this tick, by the encoders (the robot's exact
                                   kinematics); a speed metric is the step ending at this tick (empty at
                                   the first tick of the trial and after a disturbance)
    tracker.<name>_<unit>          the same metric measured by the simulated tracker (when it has noise)

A procedure's trace has, after ``violations``, ``phase`` (the phase the step solved, by name) and one
``monitor.<name>`` column per named monitor (1 when it held at the tick, else 0): :mod:`vfdsl.sim.phases`.

Metrics are in SI here (m, rad, m/s, rad/s; a share in % as a fraction), where the summary table shows mm,
deg and %. An empty CSV cell is a missing value (NaN in Parquet). The Parquet file carries the same columns
(float64, int64 and string) and, in its schema metadata, ``vfdsl.task`` and ``vfdsl.file``.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from vfdsl.compiler.context import flatten
from vfdsl.errors import VfError
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir

FORMATS = (".csv", ".parquet", ".mcap")
_SI_SUFFIX = {"mm": "m", "deg": "rad", "mm/s": "m_s", "deg/s": "rad_s", "%": ""}
_DISPLAY_SUFFIX = {"mm": "mm", "deg": "deg", "mm/s": "mm_s", "deg/s": "deg_s", "%": "pct"}
_SCALAR_UNITS = {"length": "_m", "angle": "_rad", "speed": "_m_s", "angular_speed": "_rad_s", "number": "",
                 "time": "_s", "force": "_N"}
_XYZ_M = ("x_m", "y_m", "z_m")
_PARAM_PARTS = {"point": _XYZ_M, "vector": _XYZ_M, "direction": ("x", "y", "z"),
                "line": ("px_m", "py_m", "pz_m", "dx", "dy", "dz"),
                "plane": ("px_m", "py_m", "pz_m", "nx", "ny", "nz"),
                "pose": _XYZ_M + ("roll_rad", "pitch_rad", "yaw_rad")}
_GRID_UNITS = {"duration": "_s", "period": "_s", "latency": "_s", "servo_lag": "_s", "noise": "_m"}


def joint_columns(prefix: str, names, types) -> list[str]:
    return [f"{prefix}.{n}_{'m' if t == 'prismatic' else 'rad'}" for n, t in zip(names, types)]


def input_columns(task: ir.Task) -> list[str]:
    return [f"input.{i.name}.{part}" for i in task.inputs for part in INPUT_TYPES[i.type].columns]


def param_columns(decl: ir.ParamDecl) -> list[str]:
    """The columns of one run-time param, in the order of its flat run-time value."""
    if decl.type == "curve":
        return [f"param.{decl.name}.p{i}.{part}" for i in range(len(decl.value.points)) for part in _XYZ_M]
    if decl.type in _PARAM_PARTS:
        return [f"param.{decl.name}.{part}" for part in _PARAM_PARTS[decl.type]]
    return [f"param.{decl.name}{_SCALAR_UNITS.get(decl.type, '')}"]


def runtime_params(task: ir.Task) -> list[ir.ParamDecl]:
    """The params the controller takes at run time (a curve fixed at compile time is not one)."""
    return [d for d in task.params if flatten(d.value)]


def flat_param(value) -> np.ndarray:
    """A param's run-time value as flat numbers: an IR value, or the array a motion writes."""
    if hasattr(value, "model_dump"):
        return np.asarray(flatten(value), dtype=float)
    return np.asarray(value, dtype=float).ravel()


def metric_column(source: str, name: str, unit: str) -> str:
    """``metric.tip_error_m`` for the metric ``tip_error_mm``: its name with the SI unit (and any
    ``_line<N>`` suffix kept); a share in % is a fraction, without a unit (``metric.wall_contact``)."""
    suffix = f"_{_DISPLAY_SUFFIX[unit]}"
    at = name.rfind(suffix)
    rest = name[at + len(suffix):] if at >= 0 else ""
    base = name[:at] if at >= 0 else name
    if rest and not rest.startswith("_line"):
        base, rest = name, ""
    si = _SI_SUFFIX[unit]
    return f"{source}.{base}{'_' + si if si else ''}{rest}"


def metric_factor(unit: str) -> float:
    """From a metric's display unit to SI."""
    return {"mm": 1e-3, "deg": math.pi / 180, "mm/s": 1e-3, "deg/s": math.pi / 180, "%": 0.01}[unit]


def per_tick(parts: list[np.ndarray], lengths: list[int]) -> np.ndarray:
    """A metric's values, scored segment by segment (one sample per tick, vfdsl.sim.metrics), as one array."""
    for part, n in zip(parts, lengths):
        if len(part) != n:
            raise ValueError(f"a metric of {len(part)} samples for a segment of {n} ticks")
    return np.concatenate([np.asarray(part, dtype=float) for part in parts]) if parts else np.zeros(0)


def columns(results) -> tuple[list[str], list[list]]:
    """The trace of every trial with one: column names and one list of values per column."""
    traced = [r for r in results if r.trace is not None]
    if not traced:
        return [], []
    grid_names = [name for name, _ in traced[0].grid]
    traced_names = list(dict.fromkeys(name for r in traced for name in r.trace))   # a grid point without a tracker
    names = ["trial", "seed", *(f"{g}{_GRID_UNITS.get(g, '')}" for g in grid_names), *traced_names]
    data: list[list] = [[] for _ in names]
    for r in traced:
        n = len(r.trace["tick"])
        fixed = [r.trial, r.seed, *(value for _, value in r.grid)]
        for i, value in enumerate(fixed):
            data[i].extend([value] * n)
        for i, name in enumerate(traced_names, start=len(fixed)):
            column = r.trace.get(name, [math.nan] * n)                       # has none of its columns: missing
            data[i].extend(column.tolist() if hasattr(column, "tolist") else column)
    return names, data


def check_path(name: str) -> str:
    """The trace format of an output path, from its suffix; Parquet needs pyarrow."""
    suffix = Path(name).suffix.lower()
    if suffix not in FORMATS:
        raise VfError(f"--trace {name}: write a .csv, a .parquet or an .mcap file")
    if suffix == ".parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise VfError(f"--trace {name}: Parquet needs pyarrow",
                          hint="pip install pyarrow, or write a .csv") from None
    return suffix


def write(path: Path, results, task_name: str, task_file: str) -> None:
    names, data = columns(results)
    if path.suffix.lower() == ".parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.table({n: d for n, d in zip(names, data)})
        table = table.replace_schema_metadata({"vfdsl.task": task_name, "vfdsl.file": task_file})
        pq.write_table(table, path)
        return
    with path.open("w", newline="") as out:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(names)
        writer.writerows(zip(*([_cell(x) for x in column] for column in data)))


def _cell(x):
    if isinstance(x, float):
        return "" if math.isnan(x) else repr(x)
    return x
