"""Aggregating trials into one result: the summary table, the JSON document and the per-trial CSV.

Statistics pool every tick of every trial of a grid point, merged in trial order, so a run gives the same
numbers however its trials were scheduled (in this process, a process pool or a Dask cluster).
"""

from __future__ import annotations

import csv
import io
import json
import math

import vfdsl
from vfdsl.sim.metrics import Stats
from vfdsl.sim.runner import TrialResult
from vfdsl.sim.settings import SimSettings


def groups(results: list[TrialResult]) -> list[tuple[tuple, list[TrialResult]]]:
    """Results by grid point, in the order of the first trial of each."""
    out: dict[tuple, list[TrialResult]] = {}
    for r in results:
        out.setdefault(r.grid, []).append(r)
    return list(out.items())


def pooled(results: list[TrialResult]) -> dict[str, Stats]:
    total: dict[str, Stats] = {}
    for r in sorted(results, key=lambda r: r.trial):
        for name, stats in r.stats.items():
            total[name] = total.get(name, Stats()).merge(stats)
    return total


def paper_figures(settings: SimSettings) -> dict[str, tuple[float, float]]:
    """The paper's (mean, std) beside our metric names: encoders for a metric, tracker for tracker_*."""
    out = {}
    for spec in settings.metrics:
        unit = "deg" if spec.tilt_of else None
        for source, figure in spec.paper.items():
            for suffix in (("_mm", "_deg") if unit is None else ("_deg",)):
                name = f"{spec.name}{suffix}"
                out[name if source == "encoders" else f"tracker_{name}"] = figure
    return out


def document(task_name: str, task_file: str, settings: SimSettings, results: list[TrialResult],
             grid: list[tuple[str, list]] | None) -> dict:
    """The whole run as JSON data: settings, seed, metrics (per grid point when there is a grid), trials."""
    paper = paper_figures(settings)
    units = {name: unit for r in results for name, unit in r.units.items()}    # a grid point without a tracker

    def metrics_of(rs: list[TrialResult]) -> dict:
        return {name: {**stats.summary(), "unit": units[name],
                       **({"paper": {"mean": paper[name][0], "std": paper[name][1]}} if name in paper else {})}
                for name, stats in pooled(rs).items()}

    doc = {"vfdsl": vfdsl.__version__, "task": task_name, "file": task_file, "seed": settings.seed,
           "settings": settings.summary(), "hand": results[0].hand,
           "fallback_ticks": sum(r.fallback_ticks for r in results),
           "uncertified_ticks": sum(r.uncertified_ticks for r in results), "ticks": sum(r.ticks for r in results)}
    if grid:
        doc["grid"] = {name: values for name, values in grid}
        doc["groups"] = [{"settings": dict(point), "metrics": metrics_of(rs)} for point, rs in groups(results)]
    else:
        doc["metrics"] = metrics_of(results)
    doc["motion"] = motion(results)
    phases = procedure(results)
    if phases is not None:
        doc["procedure"] = phases
    teleoperated = [{"trial": r.trial, **dict(r.grid), **r.teleop} for r in results if r.teleop is not None]
    if teleoperated:
        doc["teleop"] = teleoperated
    doc["trials"] = trial_rows(results)
    return doc


def motion(results: list[TrialResult]) -> dict | None:
    """How far the hand moved its frame, by the encoders, as the mean over the trials: its origin's path
    length and net displacement (mm), the angle its tool axis turned from start to end (deg), and for every
    tracked part the hand commanded the fraction of the commanded motion the robot made, the mean over the trials
    that commanded it (:func:`vfdsl.sim.runner.commanded_fraction`)."""
    moved = [r.motion for r in results if r.motion is not None]
    if not moved:
        return None
    parts = dict.fromkeys(name for m in moved for name in m.get("commanded", {}))
    fractions = {name: [m["commanded"][name] for m in moved if name in m.get("commanded", {})] for name in parts}
    return {"frame": moved[0]["frame"], "trials": len(moved),
            "path_mm": 1e3 * sum(m["path"] for m in moved) / len(moved),
            "net_mm": 1e3 * sum(m["net"] for m in moved) / len(moved),
            "turn_deg": math.degrees(sum(m["turn"] for m in moved) / len(moved)),
            "commanded_fraction": {name: sum(f) / len(f) for name, f in fractions.items()}}


def procedure(results: list[TrialResult]) -> dict | None:
    """A procedure's run per phase, over every trial (:mod:`vfdsl.sim.phases`): its mean time, every visit (trial,
    entry and exit tick and time), each metric pooled over its ticks; and every transition (trial, tick, time,
    source, target, guard)."""
    runs = [r for r in sorted(results, key=lambda r: (r.grid, r.trial)) if r.procedure is not None]
    if not runs:
        return None
    phases = []
    for k, first in enumerate(runs[0].procedure["phases"]):
        parts = [r.procedure["phases"][k] for r in runs]
        metrics = {}
        for name in first["metrics"]:
            total = Stats()
            for part in parts:
                total = total.merge(part["metrics"][name])
            metrics[name] = {**total.summary(), "unit": runs[0].units[name]}
        phases.append({"name": first["name"], "time_s": sum(p["time_s"] for p in parts) / len(parts),
                       "visits": [{"trial": r.trial, **dict(r.grid), **v} for r, p in zip(runs, parts)
                                  for v in p["visits"]],
                       "metrics": metrics})
    transitions = [{"trial": r.trial, **dict(r.grid), **e} for r in runs for e in r.procedure["transitions"]]
    return {"phases": phases, "transitions": transitions}


def phase_table(doc: dict) -> str:
    """A procedure's report: per phase its mean time and its visits (entry and exit, tick and time), the
    transitions with their guards, and each phase's metrics (mean and max over its ticks)."""
    proc, grid = doc["procedure"], list(doc.get("grid", {}))
    several = len({(v["trial"], *(v[g] for g in grid)) for p in proc["phases"] for v in p["visits"]}) > 1

    def who(row: dict) -> str:
        """'trial 1, period 0.01: ' when the run has several trials or grid points."""
        return ", ".join([f"trial {row['trial']}"] + [f"{g} {row[g]:g}" for g in grid]) + ": " if several else ""

    lines = [f"{'phase':<12} {'time (s)':>9}  visits: entered at tick (s) -> left at tick (s)"]
    for p in proc["phases"]:
        visits = ", ".join(f"{who(v)}{v['entry_tick']} ({v['entry_s']:.3f} s) -> "
                           + ("end" if v["exit_tick"] is None else f"{v['exit_tick']} ({v['exit_s']:.3f} s)")
                           for v in p["visits"]) or "not entered"
        lines.append(f"{p['name']:<12} {p['time_s']:>9.3f}  {visits}")
    lines += ["", "transitions: tick (s), from -> to, the guard that held"]
    for e in proc["transitions"]:
        lines.append(f"  {who(e)}{e['tick']} ({e['time_s']:.3f} s)  {e['source']} -> {e['target']}  when {e['guard']}")
    width = _name_width(name for p in proc["phases"] for name in p["metrics"])
    lines += ["", f"{'phase':<12} {'metric':<{width}} {'unit':<6} {'mean':>10} {'max':>10}"]
    for p in proc["phases"]:
        for name, m in p["metrics"].items():
            if m["samples"]:
                lines.append(f"{p['name']:<12} {name:<{width}} {m['unit']:<6} {_num(m['mean'])} {_num(m['max'])}")
    return "\n".join(lines)


def trial_rows(results: list[TrialResult]) -> list[dict]:
    """One row per trial: its grid settings, seed, and each metric's mean, min and max."""
    rows = []
    for r in results:
        row = {"trial": r.trial, "seed": r.seed, **dict(r.grid), "fallback_ticks": r.fallback_ticks,
               "uncertified_ticks": r.uncertified_ticks}
        if r.motion is not None:
            row.update({"motion.path_mm": 1e3 * r.motion["path"], "motion.net_mm": 1e3 * r.motion["net"],
                        "motion.turn_deg": math.degrees(r.motion["turn"])})
        for name, stats in r.stats.items():
            row[f"{name}.mean"] = stats.mean
            row[f"{name}.min"] = stats.least
            row[f"{name}.max"] = stats.worst
        rows.append(row)
    return rows


def to_json(doc: dict) -> str:
    return json.dumps(doc, indent=2, sort_keys=False, default=_plain) + "\n"


def to_csv(doc: dict) -> str:
    rows = doc["trials"]
    out = io.StringIO()
    columns = dict.fromkeys(name for row in rows for name in row)      # a metric a grid point lacks: an empty cell
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return out.getvalue()


def _plain(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"not JSON data: {type(value).__name__}")


def table(doc: dict, tolerances: dict[str, float]) -> str:
    """The summary table a user reads: per grid point, each metric's mean, std, min and max over the trials,
    its tolerance, and the paper's figure beside it."""
    blocks = doc["groups"] if "groups" in doc else [{"settings": {}, "metrics": doc["metrics"]}]
    lines = []
    width = _name_width(name for block in blocks for name in block["metrics"])
    header = (f"{'metric':<{width}} {'unit':<6} {'mean':>10} {'std':>10} {'min':>10} {'max':>10} {'tolerance':>10}  "
              "paper (mean ± std)")
    for block in blocks:
        if block["settings"]:
            lines.append("")
            lines.append(", ".join(f"{k} = {_setting(k, v)}" for k, v in block["settings"].items()))
        lines.append(header)
        for name, m in block["metrics"].items():
            paper = f"{m['paper']['mean']:g} ± {m['paper']['std']:g}" if "paper" in m else ""
            tol = tolerances.get(name.removeprefix("tracker_"))
            shown = [m[k] if m.get("samples", 1) else math.nan for k in ("mean", "std", "min", "max")]   # (a phase
            lines.append(f"{name:<{width}} {m['unit']:<6} {' '.join(_num(x) for x in shown)} "   # never entered: -)
                         f"{_num(tol) if tol is not None else ' ' * 10}  {paper}")
    return "\n".join(lines)


def _name_width(names) -> int:
    """The metric column's width: 34, or the longest name's."""
    return max([34, *(len(name) for name in names)])


def _num(x: float) -> str:
    return f"{x:>10.3g}" if math.isfinite(x) else f"{'-':>10}"


def _setting(name: str, value) -> str:
    if name in ("period", "latency", "servo_lag", "duration"):
        return f"{value * 1e3:g} ms" if value < 1 else f"{value:g} s"
    if name == "noise":
        return f"{value * 1e3:g} mm"
    return str(value)
