"""The live loop: the user's hand as the task's first input, the controller run at the task's period.

The hand: its offset from the tool's rest pose is the task's first input. The rest pose is the tracked
frame (the frame of the first ``track`` term that reads the input): a force is ``k (p_hand - p_tool)`` with
``k = 1 / (gain T)``, so the tool reaches a still hand in about T = 0.5 s where the fixture lets it; a torque
comes from the hand's rotation and, where the input has no force part, from the hand held on the shaft
LEVER up the tool axis (the torque of the spring force about the frame); a twist is the offset over T.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from vfdsl.errors import VfError
from vfdsl.inputs import INPUT_TYPES
from vfdsl.inputs.base import InputType
from vfdsl.ir import model as ir
from vfdsl.objectives.track import commanded_motion
from vfdsl.runtime.values import ASSUMED_PERIOD
from vfdsl.view.scene import DRAW_RATE, matrix, wxyz
from vfdsl.view.teleop import MasterModel, master_model, teleop_line

REACH_TIME = 0.5            # s: the hand's spring brings the tool to a still hand in about this time
LEVER = 0.05                # m: where a torque-only hand holds the tool, up its axis
HAND_SCALE = 0.025          # m: size of the hand's transform controls
RIPPLE = 1e-6               # the hand's reading of a procedure alternates by +-RIPPLE (SI: N, Nm, m/s, rad/s)


@dataclass
class HandModel:
    """How the hand's pose becomes the first input."""

    input: ir.InputDecl
    frame: str
    gain: float
    angular_gain: float

    @property
    def kind(self) -> InputType:
        return INPUT_TYPES[self.input.type]

    @property
    def linear(self) -> bool:
        return self.kind.linear is not None

    @property
    def angular(self) -> bool:
        return self.kind.angular is not None

    @property
    def lever(self) -> float:
        return LEVER if not self.linear else 0.0

    def rest(self, pose) -> tuple[np.ndarray, np.ndarray]:
        return pose.position + self.lever * pose.tool_axis, pose.rotation

    def value(self, pose, position, rotation) -> np.ndarray:
        p0, R0 = self.rest(pose)
        offset = np.asarray(position) - p0
        turn = Rotation.from_matrix(np.asarray(rotation) @ R0.T).as_rotvec()
        T = REACH_TIME
        out = np.zeros(self.kind.size)
        for angular, motion, gain in ((False, offset, self.gain), (True, turn, self.angular_gain)):
            part = self.kind.angular if angular else self.kind.linear
            if part is not None and part.rate:                    # a velocity: the hand's motion over T
                out[self.kind.part_range(angular)] = motion / T
            elif part is not None and gain:                       # a force or torque: the spring's
                out[self.kind.part_range(angular)] = motion / (gain * T)
        if self.angular and not self.linear and self.angular_gain:     # torque only: the spring on the shaft turns the tool
            out += np.cross(self.lever * pose.tool_axis, offset) / (self.angular_gain * T * self.lever ** 2)
        return out

    def commanded(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(v, w) the track term asks for (m/s, rad/s): its symbolic commanded motion, evaluated."""
        v, w = commanded_motion(self.input.type)(u, self.gain, self.angular_gain)
        return v.full().ravel(), w.full().ravel()


def control_period(task: ir.Task) -> float:
    """The period the viewer runs the controller at (s): the task's, else ASSUMED_PERIOD."""
    return float(task.scene.period or ASSUMED_PERIOD)


def hand_model(task: ir.Task, phase: str | None = None) -> HandModel | MasterModel | None:
    """The hand on the task's first input that has a motion part (a button is never the hand's): the frame and
    gains of the first ``track`` term reading it, among the task's terms held in every phase, then those of
    ``phase`` (or, without one, of each phase in order). A teleoperated task's hand is its master
    (:class:`vfdsl.view.teleop.MasterModel`)."""
    master = master_model(task)
    if master is not None:
        return master
    decl = next((d for d in task.inputs if INPUT_TYPES[d.type].linear or INPUT_TYPES[d.type].angular), None)
    if decl is None:
        return None
    phases = [p for p in task.phases if phase is None or p.name == phase]
    for o in list(task.objectives) + [o for p in phases for o in p.objectives]:
        if o.term == "track" and getattr(o.args.get("input"), "name", None) == decl.name:
            gain = o.args.get("gain")
            angular = o.args.get("angular_gain")
            default = INPUT_TYPES[decl.type].default_gain or 0.0
            return HandModel(decl, o.args["frame"].name,
                             float(gain.value.value) if isinstance(gain, ir.Const) else default,
                             float(angular.value.value) if isinstance(angular, ir.Const) else default)
    return HandModel(decl, task.frames[0].name, 1e-3, 0.1) if task.frames and phase is None else None


class LiveLoop:
    """The viewer's live mode: the hand (:meth:`push`), one control tick (:meth:`tick`) and the loop that
    runs it (:meth:`start_live`)."""

    def start_live(self) -> None:
        """Run the controller at the task's period in a background thread (live mode)."""
        if self.replay is not None or self._thread is not None:
            return
        self._thread = threading.Thread(target=self._loop, name="vfdsl-view-loop", daemon=True)
        self._thread.start()

    def push(self, offset) -> None:
        """Put the hand at the tool's rest pose plus ``offset`` (m, world), as a user dragging it would."""
        if self.hand is None:
            raise VfError(f"task '{self.task.name}' has no input: there is no hand to push")
        with self.lock:
            pose = self.frames[self.hand.frame]
            p0, R0 = self.hand.rest(pose)
            self.hand_node.position = p0 + np.asarray(offset, dtype=float)
            self.hand_node.wxyz = wxyz(R0)

    def _add_hand(self) -> None:
        """The hand's transform controls, at the tool's rest pose."""
        p0, R0 = self.hand.rest(self.frames[self.hand.frame])
        self.hand_node = self.server.scene.add_transform_controls(
            "/hand", scale=HAND_SCALE, position=p0, wxyz=wxyz(R0), disable_rotations=not self.hand.angular,
            depth_test=False)
        self.nodes["/hand"] = self.hand_node

    def _zero_inputs(self) -> dict:
        return {d.name: np.zeros(d.size) for d in self.task.inputs}

    def _static_step(self) -> None:
        """One step with the hands off at the current state, not applied: which rows are violated here. A
        procedure's machine, which the step advanced, is put back to its initial phase."""
        try:
            self.ctrl.step(self.q, self._zero_inputs(), params=self.overrides or None, dt=self.period)
        except VfError as err:
            self._show_error(str(err))
            return
        finally:
            self.ctrl.reset()
        self._read_status()
        self._read_procedure()

    def _loop(self) -> None:
        next_tick = time.perf_counter()
        self._rate_mark = (time.perf_counter(), self.ticks)
        draw_every = max(1, round(1.0 / (DRAW_RATE * self.period)))
        while not self._stop.is_set():
            if getattr(self, "run_box", None) is None or self.run_box.value:
                try:
                    self.tick(draw=self.ticks % draw_every == 0)
                except Exception as err:          # shown, and the loop goes on: the viewer never dies of a tick
                    self._show_error(f"tick failed: {type(err).__name__}: {err}")
            next_tick += self.period
            delay = next_tick - time.perf_counter()
            if delay > 0:
                self._stop.wait(delay)
            else:
                next_tick = time.perf_counter()

    def tick(self, draw: bool = True) -> None:
        """One control tick: the hand's input (zero inputs for a task without one), one controller step, the
        new state."""
        with self.lock:
            inputs = self._zero_inputs()
            hand = self.hand
            if hand is not None:
                before = self.frames[hand.frame]
                u = hand.value(before, self.hand_node.position, matrix(self.hand_node.wxyz))
                inputs[hand.input.name] = u + (RIPPLE * (-1) ** self.ticks if self.task.phases else 0.0)
            self._press_buttons(inputs)
            try:
                dq = self.ctrl.step(self.q, inputs, params=self.overrides or None, dt=self.period)
            except VfError as err:
                self._show_error(str(err))
                return
            self.q = self.q + dq
            self.ticks += 1
            self.time += self.period
            self.frames = self.ctrl.frames(self.q)
            self._read_status()
            self._read_procedure()
            if self.ctrl.events:
                self.hand = hand_model(self.task, self.phase) or hand
                self._write_status()
            if self.ctrl.teleop is not None:
                self.readout = teleop_line(self.ctrl.teleop)
            elif hand is not None:
                after = self.frames[hand.frame]
                v_cmd, w_cmd = hand.commanded(u)
                v = (after.position - before.position) / self.period
                w = Rotation.from_matrix(after.rotation @ before.rotation.T).as_rotvec() / self.period
                self.readout = _tracking(v_cmd, v, w_cmd, w, hand.linear)
            else:
                self.readout = "no input: the task runs hands off"
            if draw:
                self._draw_state()
                self._draw_fixtures()

    def _read_status(self) -> None:
        self.status = self.ctrl.status
        self.violations = self.ctrl.violations()
        violated = set()
        for v in self.violations:
            k = self._constraint_of.get((v.label.primitive, v.label.frame, v.label.span))
            if k is not None:
                violated.add(k)
        if violated != self._violated:
            changed = violated ^ self._violated
            self._violated = violated
            for f in getattr(self, "fixtures", []):
                if f.index in changed:
                    self._draw_fixture(f)


def _tracking(v_cmd, v, w_cmd, w, linear: bool) -> str:
    """``asked 5.00 mm/s, moved 4.98 mm/s (100% along, 0.01 mm/s across)``, or the same in deg/s."""
    if linear:
        asked, got, unit, scale = v_cmd, v, "mm/s", 1e3
    else:
        asked, got, unit, scale = w_cmd, w, "deg/s", 180 / math.pi
    n = float(np.linalg.norm(asked))
    if n < 1e-12:
        return f"hands off · moving {np.linalg.norm(got) * scale:.3g} {unit}"
    along = float(np.dot(got, asked)) / n
    across = float(np.linalg.norm(got - along * asked / n))
    return (f"asked {n * scale:.3g} {unit}, moved {np.linalg.norm(got) * scale:.3g} {unit} "
            f"({along / n:.0%} along, {across * scale:.3g} {unit} across)")
