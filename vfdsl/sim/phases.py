"""A procedure's run, tick by tick and per phase (docs/simulate.md, "Procedures").

Each tick the simulator records the phase the controller solved (``Controller.phase`` after the step: a
transition's new phase from its own tick on), every named monitor (``Controller.monitors``) and the transitions
(``Controller.events``). From these, per phase: its visits (entry tick, and exit tick: the tick of the transition
out, the first tick of the next phase; none for the phase the run ends in), its time (ticks x period), and each
metric of the run pooled over the phase's ticks. Times are the ticks' times k x period, as in the trace.
"""

from __future__ import annotations

import numpy as np

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

    def tick(self, k: int, ctrl, period: float) -> None:
        self.phase[k] = self._index[ctrl.phase]
        values = ctrl.monitors
        for i, name in enumerate(self.monitors):
            self.held[k, i] = values[name]
        for e in ctrl.events:
            self.events.append({"tick": k, "time_s": k * period, "source": e.source, "target": e.target,
                                "guard": e.guard})

    def columns(self) -> dict:
        """The trace's columns: ``phase`` (its name) and ``monitor.<name>`` (1 when it held at the tick, else 0)."""
        out: dict = {"phase": [self.names[k] for k in self.phase]}
        out.update({f"monitor.{name}": self.held[:, i] for i, name in enumerate(self.monitors)})
        return out

    def summary(self, period: float, metrics: dict[str, np.ndarray]) -> dict:
        """Per phase (in declaration order): ticks, time, visits and the metrics over its ticks; the transitions."""
        entries = [(self.initial, 0)] + [(e["target"], e["tick"]) for e in self.events]
        ends = [tick for _, tick in entries[1:]] + [None]
        phases = []
        for k, name in enumerate(self.names):
            mask = self.phase == k
            visits = [{"entry_tick": start, "entry_s": start * period, "exit_tick": end,
                       "exit_s": None if end is None else end * period}
                      for (entered, start), end in zip(entries, ends) if entered == name]
            phases.append({"name": name, "ticks": int(mask.sum()), "time_s": float(mask.sum()) * period,
                           "visits": visits, "metrics": {m: Stats().add(v[mask]) for m, v in metrics.items()}})
        return {"phases": phases, "transitions": list(self.events)}
