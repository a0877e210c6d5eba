"""Plots of a run (matplotlib, PNG), after the paper's figures.

- a task with a curve (experiment A, Fig. 6): the tip's path over the curve, in the curve's frame, and the
  error profiles;
- a task with a cone (experiment B, Figs. 9 and 10): a point up the tool shaft tracing its circle around
  the cone axis beside the desired circle, and the error profiles (encoders and tracker);
- any other task: the tracked frame's path in the world x-y plane, and the error profiles;
- a grid (Fig. 7): the first metric's profile for each grid point, one panel each, on one scale;
- a procedure: its phases as coloured bands behind each profile (one trial's figure);
- a teleoperated task: the haptic force and the tool's error to the scaled command over time, with the ticks where
  a fixture acted shaded.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend is chosen first)
import numpy as np  # noqa: E402

from vfdsl.ir import model as ir  # noqa: E402
from vfdsl.sim.geometry import Curve, Scene, unit  # noqa: E402
from vfdsl.sim.runner import TrialResult  # noqa: E402
from vfdsl.sim.settings import SimSettings  # noqa: E402

MM = 1e3


def plot_run(task: ir.Task, settings: SimSettings, results: list[TrialResult], grid, path: str) -> None:
    shown = [r for r in results if r.series is not None]
    if grid:
        figure = _grid_figure(task, shown)
    else:
        figure = _trial_figure(task, settings, shown[0])
    figure.savefig(path, dpi=110)
    plt.close(figure)


def _profiles(settings_metrics, series: dict) -> list[str]:
    """The metrics worth a profile: the scene's named ones, else every frame constraint's error."""
    names = [n for n in series["metrics"] if not n.startswith(("tracker_", "joint_"))]
    named = [n for n in names if any(n.startswith(spec.name + "_") for spec in settings_metrics)]
    return named or names


def _trial_figure(task: ir.Task, settings: SimSettings, result: TrialResult):
    series = result.series
    names = _profiles(settings.metrics, series)
    teleop = series.get("teleop")
    panels = 1 + len(names) + (series.get("phase") is not None) + (teleop is not None)
    figure, axes = plt.subplots(1, panels, figsize=(5.2 * panels, 4.4), squeeze=False)
    axes = axes[0]
    _trajectory(axes[0], task, settings, series)
    t = series["t"]
    for ax in axes[1:]:
        _phase_bands(ax, series)
    if teleop is not None:
        _teleop_panel(axes[-1 - (series.get("phase") is not None)], t, teleop)
    if series.get("phase") is not None:
        ax = axes[-1]
        ax.step(t, series["phase"], where="post", color="k", lw=1)
        ax.set_yticks(range(len(series["phase_names"])), series["phase_names"])
        ax.set_xlabel("time (s)")
        ax.set_title("phase")
        ax.grid(alpha=0.3)
    for ax, name in zip(axes[1:], names):
        unit_name = result.units[name]
        if f"tracker_{name}" in series["metrics"]:
            ax.plot(t, series["metrics"][f"tracker_{name}"], lw=0.5, color="C1", alpha=0.5,
                    label="simulated tracker")
        ax.plot(t, series["metrics"][name], lw=0.9, color="C0", label="robot kinematics (encoders)")
        ax.legend(loc="upper right", fontsize=8)
        for start, _ in series["segments"][1:]:
            ax.axvline(t[start], color="0.5", ls=":", lw=1)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"{name.rsplit('_', 1)[0].replace('_', ' ')} ({unit_name})")
        ax.grid(alpha=0.3)
    figure.suptitle(f"{task.name}: trial {result.trial} (seed {result.seed}), period {settings.period * 1e3:g} ms, "
                    f"latency {settings.latency * 1e3:g} ms")
    figure.tight_layout()
    return figure


def _teleop_panel(ax, t: np.ndarray, teleop: dict) -> None:
    """The haptic force (left axis) and the error to the scaled command (right axis); fixtures acting shaded."""
    acting = teleop["acting"]
    if acting.any():
        ax.fill_between(t, 0, 1, where=acting, step="post", color="C3", alpha=0.12, lw=0,
                        transform=ax.get_xaxis_transform(), label="a fixture acts")
    ax.plot(t, teleop["force"], lw=0.9, color="C1", label="haptic force")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("haptic force (N)")
    ax.grid(alpha=0.3)
    right = ax.twinx()
    right.plot(t, teleop["error"] * MM, lw=0.7, color="C0", label="error to the command")
    right.set_ylabel("error to the scaled command (mm)")
    lines = ax.get_legend_handles_labels()[0] + right.get_legend_handles_labels()[0]
    ax.legend(lines, [line.get_label() for line in lines], loc="upper right", fontsize=8)
    ax.set_title("teleoperation")


def _phase_bands(ax, series: dict) -> None:
    """A procedure's phases as bands over time (one colour per phase, named once in the legend)."""
    if series.get("phase") is None:
        return
    phase, names, t = series["phase"], series["phase_names"], series["t"]
    changes = [0, *(np.flatnonzero(np.diff(phase)) + 1), len(phase)]
    named = set()
    for start, end in zip(changes, changes[1:]):
        k = int(phase[start])
        ax.axvspan(t[start], t[end - 1] + (t[1] - t[0] if len(t) > 1 else 0.0), color=f"C{k % 10}", alpha=0.12,
                   lw=0, label=None if k in named else f"phase {names[k]}")
        named.add(k)


def _trajectory(ax, task: ir.Task, settings: SimSettings, series: dict) -> None:
    follows = next((c for c in task.constraints if c.primitive == "follows" and _unshifted(c)), None)
    cone = next((c for c in task.constraints if c.primitive == "cone"), None)
    if follows is not None:
        _curve_panel(ax, task, follows, series)
    elif cone is not None:
        _cone_panel(ax, task, cone, settings, series)
    else:
        frame = task.frames[0].name
        p = series["p"][frame] * MM
        ax.plot(p[:, 0], p[:, 1], lw=1)
        ax.plot(p[0, 0], p[0, 1], "o", ms=4, label="start")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_title(f"path of frame '{frame}'")
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=8)


def _unshifted(c: ir.Constraint) -> bool:
    """A ``follows`` of the curve itself (not of a copy shifted up the tool)."""
    shift = c.args.get("shift")
    return shift is None or not (isinstance(shift, ir.Const) and any(shift.value.xyz))


def _curve_panel(ax, task: ir.Task, c: ir.Constraint, series: dict) -> None:
    """The tip in the curve's own frame (segment by segment, as the plate moves; less the curve's displacement
    where a motion moves it) and the curve."""
    curve_arg = c.args["curve"]
    curve = Curve(task.param(curve_arg.name).value)
    s = np.linspace(0, curve.length, 800)
    points = curve.spline(s) * MM
    ax.plot(points[:, 0], points[:, 1], color="0.6", lw=3, label="reference b-spline")
    bounds = [k for k, _ in series["segments"]] + [len(series["t"])]
    local = []
    for (start, values), end in zip(series["segments"], bounds[1:]):
        scene = Scene(task).with_values(values, {name: table[start:end] for name, table in series["shifts"].items()})
        local.append(scene.local(curve_arg, series["p"][c.frame][start:end]))
    local = np.concatenate(local) * MM
    ax.plot(local[:, 0], local[:, 1], color="C0", lw=1, label=f"{c.frame} (encoders)")
    ax.set_xlabel("x on the plate (mm)")
    ax.set_ylabel("y on the plate (mm)")
    ax.set_title("tool tip over the curve")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)


def _cone_panel(ax, task: ir.Task, c: ir.Constraint, settings: SimSettings, series: dict) -> None:
    """A point up the shaft (the tracker's second marker), seen along the cone axis, and its desired circle."""
    scene = Scene(task)
    axis = scene.direction(c.args["axis"])
    angle = scene.value(c.args["angle"]).value
    frame = c.frame
    d = settings.marker_distance
    point = series["p"][frame] + d * series["axis"][frame]
    origin = series["p"][frame][0]
    e1 = unit(np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]))
    e2 = np.cross(axis, e1)
    rel = point - origin
    ax.plot(rel @ e1 * MM, rel @ e2 * MM, color="C0", lw=1, label="shaft point (encoders)")
    phase = np.arctan2(rel @ e2, rel @ e1)
    radius = d * np.sin(angle)
    ax.plot(radius * np.cos(phase[::25]) * MM, radius * np.sin(phase[::25]) * MM, ".", color="C3", ms=3,
            label="desired (on the cone)")
    ax.set_xlabel("mm, across the cone axis")
    ax.set_ylabel("mm, across the cone axis")
    ax.set_title(f"a point {d * MM:g} mm up the shaft")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8, loc="upper right")


def _grid_figure(task: ir.Task, shown: list[TrialResult]):
    name = next(n for n in shown[0].series["metrics"] if not n.startswith(("tracker_", "joint_")))
    figure, axes = plt.subplots(1, len(shown), figsize=(4.2 * len(shown), 3.8), squeeze=False, sharey=True)
    for ax, result in zip(axes[0], shown):
        ax.plot(result.series["t"], result.series["metrics"][name], lw=0.9)
        ax.set_title(", ".join(f"{k} {_label(k, v)}" for k, v in result.grid))
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(f"{name.rsplit('_', 1)[0].replace('_', ' ')} ({shown[0].units[name]})")
    figure.suptitle(f"{task.name}: {name} for each setting (trial 0)")
    figure.tight_layout()
    return figure


def _label(name: str, value) -> str:
    if name in ("period", "latency", "servo_lag", "duration"):
        return f"{value * 1e3:g} ms"
    if name == "noise":
        return f"{value * 1e3:g} mm"
    return str(value)
