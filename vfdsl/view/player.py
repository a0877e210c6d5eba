"""The replay player: a recorded trace (:mod:`vfdsl.view.replay`) shown row by row instead of the live loop.

A part of :class:`vfdsl.view.app.Viewer`: the tool's path as one coloured line (/trace), a time slider and a
Play box; each row shown sets the robot's q, the time and the run-time params the trace records.
"""

from __future__ import annotations

import threading

import numpy as np

from vfdsl.compiler.context import flatten, unflatten
from vfdsl.view.scene import DRAW_RATE


class ReplayPlayer:
    """The viewer's replay mode: the trace drawn and its panel (:meth:`_build_replay`), one row shown
    (:meth:`show_time`), and the loop that plays it."""

    def _build_replay(self) -> None:
        import matplotlib
        trace = self.replay
        frame = self.task.frames[0].name
        rows = np.unique(np.linspace(0, len(trace.t) - 1, min(len(trace.t), 3000)).astype(int))
        points = np.array([self.ctrl.frames(trace.q[i])[frame].position for i in rows])
        if len(points) > 1:
            segments = np.stack([points[:-1], points[1:]], axis=1)
            if trace.error is not None and np.isfinite(trace.error[rows]).any():
                e = np.nan_to_num(trace.error[rows], nan=0.0)
                top = float(np.max(np.abs(e))) or 1.0
                rgb = matplotlib.colormaps["viridis"](np.abs(e) / top)[:, :3]
                colors = np.stack([rgb[:-1], rgb[1:]], axis=1)
                legend = f"trace of `{frame}` coloured by `{trace.error_name}`: 0 (purple) to {top * 1e3:.3g} mm (yellow)"
            else:
                colors, legend = (240, 120, 0), f"trace of `{frame}`"
            self.nodes["/trace"] = self.server.scene.add_line_segments(
                "/trace", segments.astype(np.float32), colors=colors, thickness=5.0, thickness_units="screen")
        gui = self.server.gui
        with gui.add_folder("Replay"):
            gui.add_markdown(legend if len(points) > 1 else "one row")
            self.time_slider = gui.add_slider("time (s)", min=float(trace.t[0]), max=float(max(trace.t[-1], trace.t[0] + 1e-6)),
                                              step=max(self.period, (trace.t[-1] - trace.t[0]) / 2000 or 1e-3),
                                              initial_value=float(trace.t[0]))
            self.time_slider.on_update(lambda _: self.show_time(self.time_slider.value))
            self.play_box = gui.add_checkbox("Play", initial_value=False)
        self._thread = threading.Thread(target=self._replay_loop, name="vfdsl-view-replay", daemon=True)
        self._thread.start()

    def show_time(self, t: float) -> None:
        """Show the replayed row at time t (the slider follows)."""
        with self.lock:
            if abs(self.time_slider.value - t) > 1e-9:
                self.time_slider.value = float(np.clip(t, self.time_slider.min, self.time_slider.max))
            trace = self.replay
            i = trace.index_at(t)
            self.q = trace.q[i].copy()
            self.time, self.ticks = float(trace.t[i]), i
            self.frames = self.ctrl.frames(self.q)
            moved = False
            for name, rows in trace.params.items():
                row = rows[i]
                if np.all(np.isfinite(row)) and not np.allclose(row, flatten(self.scene.values[name]), rtol=0, atol=1e-12):
                    self.scene.set_value(name, unflatten(self.scene.values[name], row))
                    moved = True
            parts = []
            if trace.error is not None and np.isfinite(trace.error[i]):
                parts.append(f"{trace.error_name} = {trace.error[i] * 1e3:.4g} mm")
            if trace.status is not None and np.isfinite(trace.status[i]):
                parts.append(f"status {int(trace.status[i])}")
            self.readout = " · ".join(parts)
            self._replay_procedure(i)
            self._draw_state()
            self._draw_fixtures(force=moved)

    def _replay_loop(self) -> None:
        while not self._stop.is_set():
            if self.play_box.value:
                t = self.time_slider.value + 1.0 / DRAW_RATE
                if t > self.replay.t[-1]:
                    t = float(self.replay.t[0])
                self.show_time(t)
            self._stop.wait(1.0 / DRAW_RATE)
