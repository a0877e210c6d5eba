"""A procedure's run, tick by tick and per phase (docs/simulate.md, "Procedures").

Each tick the simulator records the phase the controller solved (``Controller.phase`` after the step: a
transition's new phase from its own tick on), every named monitor (``Controller.monitors``), the transitions
(``Controller.events``) and, at the first tick and at each transition, the captured values
(``Controller.captures``: the metrics of the phases' fixtures read them, :mod:`vfdsl.ir.captures`). From these,
per phase: its visits (entry tick, and exit tick: the tick of the transition out, the first tick of the next phase;
none for the phase the run ends in), its time (ticks x period), and each metric of the run pooled over the phase's
ticks: those of the fixtures held in every phase, and its own fixtures' (measured only while it is current). Times
are the ticks' times k x period, as in the trace.
"""

from __future__ import annotations

import numpy as np

from vfdsl.ir import captures
from vfdsl.ir import model as ir
from vfdsl.sim.metrics import Stats


class PhaseRecord:
    """One trial's phases, monitors and transitions, in arrays allocated once."""

    def __init__(self, task: ir.Task, ticks: int):
        self.names = [p.name for p in task.phases]
        self.monitors = [m.name for m in task.monitors]
        self._index = {name: k for k, name in enumerate(self.names)}
        self.initial = next(p.name for p in task.phases if p.initial)
        self.phase = np.zeros(ticks, dtype=np.int64)
        self.held = np.zeros((ticks, len(self.monitors)), dtype=np.int64)
        self.events: list[dict] = []
        self.task = task
        self.captures: list[tuple[int, dict[str, ir.Value]]] = []     # (tick, the capture params' values from it)

    def tick(self, k: int, ctrl, period: float) -> None:
        self.phase[k] = self._index[ctrl.phase]
        values = ctrl.monitors
        for i, name in enumerate(self.monitors):
            self.held[k, i] = values[name]
        for e in ctrl.events:
            self.events.append({"tick": k, "time_s": k * period, "source": e.source, "target": e.target,
                                "guard": e.guard})
        if k == 0 or ctrl.events:
            self.captures.append((k, captures.values(self.task, ctrl.captures)))

    def segments(self, scene_segments: list[tuple[int, dict]]) -> list[tuple[int, dict]]:
        """The run's scored segments (tick, params' values from it) cut also where the captured values change,
        each snapshot with the capture params' values (:func:`vfdsl.ir.captures.as_params`)."""
        ticks = sorted({k for k, _ in scene_segments} | {k for k, _ in self.captures})
        out = []
        for k in ticks:
            scene = next(v for start, v in reversed(scene_segments) if start <= k)
            held = next((v for start, v in reversed(self.captures) if start <= k), {})
            out.append((k, {**scene, **held}))
        return out

    def mask(self, metric_phase: str | None, values: np.ndarray) -> np.ndarray:
        """A metric's values, NaN at the ticks its phase is not current (as they are for a metric of every
        phase)."""
        if metric_phase is None:
            return values
        return np.where(self.phase == self._index[metric_phase], values, np.nan)

    def columns(self) -> dict:
        """The trace's columns: ``phase`` (its name) and ``monitor.<name>`` (1 when it held at the tick, else 0)."""
        out: dict = {"phase": [self.names[k] for k in self.phase]}
        out.update({f"monitor.{name}": self.held[:, i] for i, name in enumerate(self.monitors)})
        return out

    def summary(self, period: float, metrics: dict[str, np.ndarray], owners: dict[str, str | None]) -> dict:
        """Per phase (in declaration order): ticks, time, visits and the metrics over its ticks (of ``metrics``,
        those whose owner, in ``owners``, is None or the phase); the transitions."""
        entries = [(self.initial, 0)] + [(e["target"], e["tick"]) for e in self.events]
        ends = [tick for _, tick in entries[1:]] + [None]
        phases = []
        for k, name in enumerate(self.names):
            mask = self.phase == k
            visits = [{"entry_tick": start, "entry_s": start * period, "exit_tick": end,
                       "exit_s": None if end is None else end * period}
                      for (entered, start), end in zip(entries, ends) if entered == name]
            phases.append({"name": name, "ticks": int(mask.sum()), "time_s": float(mask.sum()) * period,
                           "visits": visits, "metrics": {m: Stats().add(v[mask]) for m, v in metrics.items()
                                                         if owners[m] in (None, name)}})
        return {"phases": phases, "transitions": list(self.events)}
