"""A procedure in the viewer: its phase, monitors and last transition in the panel, its button inputs pressed.

A part of :class:`vfdsl.view.app.Viewer`, active only for a task with phases (a task without shows nothing new).
Live, after each tick the panel's **Procedure** folder shows ``Controller.phase``, each named monitor (on/off) and
the last of ``Controller.events`` (from -> to, guard, time); replayed, the trace's ``phase`` and ``monitor.<name>``
columns at the row shown, the last transition being the last change of phase at or before it.

Buttons: each button input gets a **press** button and a **hold** box. A press sets the input to 1 for
PRESS_TIME (100 ms, as a bare time in a simulation scene's ``buttons:``), i.e. for round(PRESS_TIME / period) ticks
(at least one) from the next tick on; holding the press button keeps renewing it; the hold box keeps the input at 1
while it is ticked. Otherwise a button is 0: the hand never drives one.
"""

from __future__ import annotations

import numpy as np

from vfdsl.errors import VfError
from vfdsl.inputs import INPUT_TYPES
from vfdsl.sim.settings import PRESS_TIME
from vfdsl.view.live import hand_model


class ProcedurePanel:
    """The viewer's procedure: :meth:`press`, :meth:`reset_procedure`, the panel's Procedure folder."""

    @property
    def buttons(self) -> list[str]:
        """The task's button inputs (those without a motion part), in declaration order."""
        return [d.name for d in self.task.inputs if INPUT_TYPES[d.type].switch]

    def press(self, name: str, seconds: float = PRESS_TIME) -> None:
        """Press button input ``name`` for ``seconds`` from the next tick on (a running press is lengthened,
        never shortened)."""
        if name not in self.buttons:
            raise VfError(f"task '{self.task.name}' has no button input '{name}'",
                          hint=f"its buttons: {', '.join(self.buttons) or 'none'}")
        with self.lock:
            self._press_left[name] = max(self._press_left.get(name, 0), max(1, round(seconds / self.period)))

    def reset_procedure(self) -> None:
        """The procedure back to its initial phase (``Controller.reset()``), no button pressed, the hand on the
        initial phase's track term; the robot stays where it is."""
        with self.lock:
            self.ctrl.reset()
            self._press_left, self.transition = {}, None
            if self.hand is not None:
                self.hand = hand_model(self.task)
            self._read_procedure()
            self._write_status()

    # ------------------------------------------------------------------------------------------ live
    def _press_buttons(self, inputs: dict) -> None:
        """This tick's buttons into ``inputs``: 1 where pressed or held, else left at 0; a press counts down."""
        for name in self.buttons:
            box = self._hold_boxes.get(name)
            if self._press_left.get(name, 0) > 0 or (box is not None and box.value):
                inputs[name][:] = 1.0
            if self._press_left.get(name, 0) > 0:
                self._press_left[name] -= 1

    def _read_procedure(self) -> None:
        """The controller's phase, monitors and, when the last tick took one, its transition (live only)."""
        if not self.task.phases or self.replay is not None:
            return
        self.phase = self.ctrl.phase
        self.monitors = dict(self.ctrl.monitors)
        if self.ctrl.events:
            e = self.ctrl.events[-1]
            self.transition = (e.source, e.target, e.guard, self.time)     # the viewer's clock: the tick's end

    # ---------------------------------------------------------------------------------------- replay
    def _replay_procedure(self, i: int) -> None:
        """The trace's phase and monitors at row i; the last transition: the last change of phase up to it."""
        trace = self.replay
        if trace.phase is None:
            return
        self.phase = trace.phase[i]
        self.monitors = {name: bool(v[i] > 0.5) for name, v in trace.monitors.items() if np.isfinite(v[i])}
        changes = np.flatnonzero(trace.phase[1:i + 1] != trace.phase[:i])
        if changes.size:
            k = int(changes[-1]) + 1
            self.transition = (trace.phase[k - 1], trace.phase[k], None, float(trace.t[k]))
        else:
            self.transition = None

    # ----------------------------------------------------------------------------------------- panel
    def _build_procedure_gui(self) -> None:
        if not self._shows_procedure():
            return
        gui = self.server.gui
        with gui.add_folder("Procedure"):
            self.procedure_md = gui.add_markdown("")
            if self.replay is None:
                for name in self.buttons:
                    button = gui.add_button(f"press {name}", hint=f"input '{name}' 1 for "
                                            f"{PRESS_TIME * 1e3:g} ms; held: as long as held")
                    button.on_click(lambda _, n=name: self.press(n))
                    button.on_hold(lambda _, n=name: self.press(n), callback_hz=20.0)
                    self._hold_boxes[name] = gui.add_checkbox(f"hold {name}", initial_value=False)
                reset = gui.add_button("Reset procedure")
                reset.on_click(lambda _: self.reset_procedure())
        if self.replay is not None:
            self._replay_procedure(0)          # the row the time slider starts at

    def _shows_procedure(self) -> bool:
        return bool(self.task.phases) and (self.replay is None or self.replay.phase is not None)

    def _procedure_text(self) -> str:
        """``phase **insert**``, the monitors (on/off) and the last transition, as markdown lines."""
        if self.phase is None:
            return ""
        lines = [f"phase **{self.phase}**"]
        if self.monitors:
            lines.append(" · ".join(f"{name}: {'**on**' if on else 'off'}" for name, on in self.monitors.items()))
        if self.transition is None:
            lines.append("no transition yet")
        else:
            source, target, guard, t = self.transition
            lines.append(f"last transition: {source} -> {target}" + (f" when {guard}" if guard else "")
                         + f" at {t:.3f} s")
        return "  \n".join(lines)

    def _write_procedure(self) -> None:
        if self._shows_procedure():
            self.procedure_md.content = self._procedure_text()
