"""The panel: the GUI's header, status and error lines, the hand's and the fixtures' controls, the params' fields.

A part of :class:`vfdsl.view.app.Viewer`: it builds ``self.server.gui`` and writes the status from the
viewer's time, ticks, step status, readout and violations.
"""

from __future__ import annotations

import math
import time

import numpy as np

from vfdsl.ir import model as ir
from vfdsl.runtime.qp import StepStatus
from vfdsl.view.options import MAGNIFY

SHOWN_IN = {"length": (1e-3, " (mm)"), "angle": (math.pi / 180, " (deg)")}    # a scalar param's field: SI per unit


class Panel:
    """The viewer's GUI (:meth:`_build_gui`), its status line (:meth:`_write_status`) and error line
    (:meth:`_show_error`)."""

    def _build_gui(self) -> None:
        gui = self.server.gui
        gui.configure_theme(control_width="medium")
        gui.add_markdown(f"**{self.task.name}** · `{self.task.file.rsplit('/', 1)[-1]}` · "
                         f"period {self.period * 1e3:g} ms · {self.ctrl.backend}")
        self.status_md = gui.add_markdown("")
        self.error_md = gui.add_markdown("")
        self._build_procedure_gui()
        if self.replay is None and self.hand is not None:
            with gui.add_folder("Hand"):
                gui.add_markdown(f"Drag the master: its motion from where it starts is input `{self.hand.input.name}` "
                                 f"(pose); the blue ghost is where it puts `{self.hand.frame}`, the orange arrow "
                                 f"the haptic force." if self.hand.input.type == "pose" else
                                 f"Drag the hand: its offset from `{self.hand.frame}` is input "
                                 f"`{self.hand.input.name}` ({self.hand.input.type}).")
                self.run_box = gui.add_checkbox("Run controller", initial_value=True)
                release = gui.add_button("Release hand")
                release.on_click(lambda _: self.push(np.zeros(3)))
                reset = gui.add_button("Reset")
                reset.on_click(lambda _: self.reset())
        with gui.add_folder("Fixtures"):
            self.magnify_slider = gui.add_slider("Tolerance x", min=MAGNIFY[0], max=MAGNIFY[1], step=1,
                                                 initial_value=float(self.magnify))
            self.magnify_slider.on_update(lambda _: self._set_magnify(self.magnify_slider.value))
            self.fixture_boxes = {}
            for f in self.fixtures:
                c = self.task.constraints[f.index]
                box = gui.add_checkbox(f"{f.title} line {c.span.line}", initial_value=True,
                                       hint=f"{'soft' if f.soft else 'hard'}, {f.where}"
                                            + (f"; {f.tolerance_text}" if f.tolerance_text else ""))
                box.on_update(lambda event, key=f.key: self._show_fixture(key, event.target.value))
                self.fixture_boxes[f.key] = box
        if self.replay is None:
            self._build_param_gui()

    def _build_param_gui(self) -> None:
        gui = self.server.gui
        self.param_inputs = {}
        names = [n for n in self.ctrl.param_names]
        if not names:
            return
        with gui.add_folder("Params"):
            gui.add_markdown("Drag a param's gizmo in the scene, or type a value (mm, deg).")
            for name in names:
                decl = self.task.param(name)
                value = decl.value
                if isinstance(value, (ir.PointValue, ir.VectorValue)):
                    handle = gui.add_vector3(f"{name} (mm)", initial_value=tuple(np.array(value.xyz) * 1e3), step=0.1)
                    handle.on_update(lambda e, n=name: self.set_param(n, np.array(e.target.value) * 1e-3))
                elif isinstance(value, ir.DirectionValue):
                    handle = gui.add_vector3(name, initial_value=tuple(value.xyz), step=0.01)
                    handle.on_update(lambda e, n=name: self.set_param(n, list(e.target.value)))
                elif isinstance(value, ir.ScalarValue):
                    scale, unit = SHOWN_IN.get(value.dimension, (1.0, ""))
                    handle = gui.add_number(f"{name}{unit}", initial_value=value.value / scale, step=0.1 if scale != 1 else 0.01)
                    handle.on_update(lambda e, n=name, s=scale: self.set_param(n, [float(e.target.value) * s]))
                else:
                    continue
                self.param_inputs[name] = handle

    def _reset_param_fields(self) -> None:
        """The params' fields back to the task's values."""
        for name, handle in getattr(self, "param_inputs", {}).items():
            value = self.task.param(name).value
            if isinstance(value, ir.ScalarValue):
                handle.value = value.value / SHOWN_IN.get(value.dimension, (1.0, ""))[0]
            else:
                handle.value = tuple(np.array(value.xyz) * (1e3 if isinstance(value, (ir.PointValue, ir.VectorValue)) else 1.0))

    def _write_status(self) -> None:
        """Time, tick, step status and tick rate; the readout; the first violations."""
        status = "optimal" if int(self.status) == 0 else ", ".join(
            s.name.lower().replace("_", " ") for s in StepStatus if s in self.status)
        lines = [f"t = {self.time:.2f} s · tick {self.ticks} · **{status}**"]
        mark = getattr(self, "_rate_mark", None)
        if mark is not None and self.replay is None:
            now = time.perf_counter()
            if now - mark[0] > 1.0:
                self.rate = (self.ticks - mark[1]) / (now - mark[0])
                self._rate_mark = (now, self.ticks)
            if getattr(self, "rate", None):
                lines[0] += f" · {self.rate:.0f} ticks/s (period {self.period * 1e3:g} ms)"
        if self.readout:
            lines.append(self.readout)
        if self.violations:
            lines.append("violated: " + "; ".join(str(v) for v in self.violations[:4])
                         + (f" (+{len(self.violations) - 4})" if len(self.violations) > 4 else ""))
        self.status_md.content = "  \n".join(lines)
        self._write_procedure()

    def _show_error(self, text: str) -> None:
        self.message = text
        if hasattr(self, "error_md"):
            self.error_md.content = f"<span style='color:#c00'>{text}</span>" if text else ""
