"""Scripted inputs of a simulation scene: pushes over time segments, button presses, sensor noise and a teleoperation
master's path (vfdsl.sim.operator).

A procedure is driven by what the user does over time (docs/simulate.md, "Procedures")::

    pushes:                    # a constant force (push) or torque (turn) on an input over [from, to)
      - {input: hand, from: 3 s, to: 6 s, magnitude: 3 N, direction: [10, -10, -50]}
      - {input: hand, from: 6 s, magnitude: 6 N, direction: [10, -10, -50]}     # no `to`: until the end
    buttons:                   # a button input: 1 while pressed, else 0
      go: [{from: 2.5 s, to: 2.6 s}, 7 s]          # a bare time: a press of PRESS_TIME (100 ms)
    sensors:                   # white noise on an input as its sensor reads it (3-D RMS per part)
      hand: {noise: 0.02 N}

At tick k (time t = k dt) an input is the hand's value (:mod:`vfdsl.sim.hand`, when the hand drives it), plus
every push active at t (``from <= t < to``), plus the sensor's noise at k; a button is 1 while a press holds t.
A sensor's noise is what keeps a live reading from repeating exactly: a scripted constant force without it is a
frozen sensor, and a task's ``unchanged(INPUT)`` watchdog (docs/language.md) rightly fires on it.
"""

from __future__ import annotations

import math

import numpy as np
import yaml

from vfdsl import units as u
from vfdsl.compiler.geometry import homogeneous
from vfdsl.errors import VfError, suggest
from vfdsl.inputs import INPUT_TYPES, described
from vfdsl.ir import model as ir
from vfdsl.sim.geometry import Scene
from vfdsl.sim.hand import direction_arg
from vfdsl.sim.settings import PRESS_TIME, Press, Push, SensorNoise, SimSettings

PUSH_KEYS = ("input", "kind", "magnitude", "direction", "from", "to")
PUSH_KINDS = ("push", "turn")
PRESS_KEYS = ("from", "to")
SENSOR_KEYS = ("noise", "angular_noise")


# ------------------------------------------------------------------------------------------- reading
def read_pushes(reader, node: yaml.Node) -> tuple[Push, ...]:
    """The scene's ``pushes:`` list, each checked at its line (``reader``: the scene reader,
    :class:`vfdsl.sim.scene_file._Reader`)."""
    if not isinstance(node, yaml.SequenceNode):
        raise VfError("pushes is a list of mappings like {input: hand, from: 2 s, to: 3 s, magnitude: 6 N, "
                      "direction: [0, 0, -1]}", reader.pos(node))
    return tuple(_push(reader, item) for item in node.value)


def _push(reader, node: yaml.Node) -> Push:
    fields = reader.mapping(node, PUSH_KEYS, "a push")
    for key in ("input", "magnitude", "direction"):
        if key not in fields:
            raise VfError(f"a push needs '{key}'", reader.pos(node), hint="keys: " + ", ".join(PUSH_KEYS))
    name = _input(reader, fields["input"][1], "a push")
    kind = reader.text(fields["kind"][1], "kind") if "kind" in fields else "push"
    if kind not in PUSH_KINDS:
        raise VfError(f"unknown push kind '{kind}'", reader.pos(fields["kind"][1]),
                      hint="push: a force (the linear part); turn: a torque (the angular part)")
    parts = INPUT_TYPES[reader.task.input(name).type]
    part = parts.angular if kind == "turn" else parts.linear
    if part is None:
        wanted = described(lambda t: t.angular) if kind == "turn" else described(lambda t: t.linear)
        raise VfError(f"a {kind} needs {wanted}; '{name}' is a {parts.name}", reader.pos(fields["input"][1]),
                      code="E602")
    magnitude = reader.scalar(fields["magnitude"][1], part.dimension)
    if magnitude < 0:
        raise VfError("a push's magnitude must be zero or positive", reader.pos(fields["magnitude"][1]),
                      hint="reverse its direction instead", code="E602")
    reader.plausible(magnitude, part.dimension, fields["magnitude"][1], "a push's magnitude")
    start, end = _segment(reader, node, fields, default_start=0.0)
    return Push(input=name, magnitude=magnitude, direction=reader.aim(fields["direction"][1], "direction"), kind=kind,
                start=start, end=end, where=reader.pos(node))


def read_buttons(reader, node: yaml.Node) -> tuple[Press, ...]:
    """The scene's ``buttons:`` mapping: per button input a press ({from, to}), a time (a PRESS_TIME press), or a
    list of them; presses of one button must not overlap."""
    if not isinstance(node, yaml.MappingNode):
        raise VfError("buttons is a mapping from button inputs to presses, like go: {from: 2 s, to: 2.1 s} or "
                      "go: [2 s, 5 s]", reader.pos(node))
    out: list[Press] = []
    for key, (key_node, value) in reader.fields(node).items():
        name = _input(reader, key_node, "buttons")
        if not INPUT_TYPES[reader.task.input(name).type].switch:     # a button: one number, its level
            raise VfError(f"input '{name}' is a {reader.task.input(name).type}, not a button", reader.pos(key_node),
                          hint="script a force or torque with pushes:", code="E602")
        items = value.value if isinstance(value, yaml.SequenceNode) else [value]
        if not items:
            raise VfError(f"button '{name}' has no press", reader.pos(value), code="E602")
        presses = sorted((_press(reader, name, item) for item in items), key=lambda p: p.start)
        for before, after in zip(presses, presses[1:]):
            if after.start < before.end:
                raise VfError(f"this press of '{name}' ({after.start:g} s) starts before the press from "
                              f"{before.start:g} s ends ({before.end:g} s)", after.where,
                              hint="a button is either pressed or not: make the presses one", code="E602")
        out += presses
    return tuple(out)


def _press(reader, name: str, node: yaml.Node) -> Press:
    if isinstance(node, yaml.MappingNode):
        fields = reader.mapping(node, PRESS_KEYS, "a press")
        if "from" not in fields or "to" not in fields:
            raise VfError("a press needs 'from' and 'to'", reader.pos(node), hint="or a bare time: a 100 ms press",
                          code="E602")
        start, end = _segment(reader, node, fields)
    else:
        start = _time(reader, node, "a press")
        end = start + PRESS_TIME
    return Press(input=name, start=start, end=end, where=reader.pos(node))


def read_sensors(reader, node: yaml.Node) -> tuple[SensorNoise, ...]:
    """The scene's ``sensors:`` mapping: per input its noise (``noise`` on the linear part, ``angular_noise`` on
    the angular part), each in its part's unit."""
    if not isinstance(node, yaml.MappingNode):
        raise VfError("sensors is a mapping from inputs to {noise: ...}, like hand: {noise: 0.02 N}",
                      reader.pos(node))
    out = []
    for key, (key_node, value) in reader.fields(node).items():
        name = _input(reader, key_node, "sensors")
        fields = reader.mapping(value, SENSOR_KEYS, f"the sensor of '{name}'")
        parts = INPUT_TYPES[reader.task.input(name).type]
        noise = {}
        for field, part in (("noise", parts.linear), ("angular_noise", parts.angular)):
            if field not in fields:
                continue
            if part is None:
                raise VfError(f"input '{name}' is a {parts.name}: it has no "
                              f"{'angular' if field == 'angular_noise' else 'linear'} part to be noisy",
                              reader.pos(fields[field][0]), code="E602")
            noise[field] = reader.scalar(fields[field][1], part.dimension)
            if noise[field] < 0:
                raise VfError(f"{field} must be zero or positive", reader.pos(fields[field][1]), code="E602")
            reader.plausible(noise[field], part.dimension, fields[field][1], f"a sensor's {field}")
        out.append(SensorNoise(input=name, linear=noise.get("noise", 0.0), angular=noise.get("angular_noise", 0.0),
                               where=reader.pos(key_node)))
    return tuple(out)


def _input(reader, node: yaml.Node, what: str) -> str:
    name = reader.text(node, "input")
    inputs = [i.name for i in reader.task.inputs]
    if name not in inputs:
        raise VfError(f"{what}: task '{reader.task.name}' declares no input '{name}'", reader.pos(node),
                      hint=suggest(name, inputs, "inputs"), code="E602")
    return name


def _time(reader, node: yaml.Node, what: str) -> float:
    t = reader.scalar(node, u.TIME)
    if t < 0:
        raise VfError(f"{what}'s time must be zero or positive, got {t:g} s", reader.pos(node), code="E602")
    reader.plausible(t, u.TIME, node, f"{what}'s time")
    return t


def _segment(reader, node: yaml.Node, fields: dict, default_start: float | None = None) -> tuple[float, float | None]:
    """``from`` and ``to`` of a segment (``to`` after ``from``; missing: the end of the run)."""
    start = _time(reader, fields["from"][1], "a segment") if "from" in fields else default_start
    end = _time(reader, fields["to"][1], "a segment") if "to" in fields else None
    if end is not None and not end > start:
        raise VfError(f"a segment's end ({end:g} s) must come after its start ({start:g} s)",
                      reader.pos(fields["to"][1]), code="E602")
    return start, end


def late_events(settings: SimSettings, end: float) -> list[tuple[float, str, object]]:
    """Pushes and presses that start at or after ``end`` (s): (start, what, where) of each; they never happen."""
    return ([(p.start, f"the push on '{p.input}' from {p.start:g} s", p.where) for p in settings.pushes
             if p.start >= end - 1e-12]
            + [(p.start, f"the press of '{p.input}' at {p.start:g} s", p.where) for p in settings.presses
               if p.start >= end - 1e-12])


# ------------------------------------------------------------------------------------------- running
class ScriptedInputs:
    """The scene's pushes, presses and sensor noise over one trial: :meth:`apply` adds them to the tick's inputs
    in place. The noise is drawn once per trial (ticks x input size) from the trial's own generator."""

    def __init__(self, settings: SimSettings, task: ir.Task, scene: Scene, period: float, ticks: int,
                 rng: np.random.Generator, robot=None):
        self.period = period
        self.robot = robot
        self.pushes = []
        for push in settings.pushes:
            parts = INPUT_TYPES[task.input(push.input).type]
            aim = scene.direction(direction_arg(push.direction))
            self.pushes.append((push, parts.part_range(angular=push.kind == "turn"), push.magnitude * aim))
        self.presses = settings.presses
        self.operator = settings.operator
        self.recorded = () if settings.recording is None else settings.recording.inputs
        frames = [task.frame(r.expressed_in) for r in self.recorded if r.expressed_in]
        self.sensor_frames = {f.name: (f.link, homogeneous(f.offset, f.rpy)) for f in frames}
        self.noise: dict[str, np.ndarray] = {}
        for sensor in settings.sensors:
            parts = INPUT_TYPES[task.input(sensor.input).type]
            table = np.zeros((ticks, parts.size))
            for angular, rms in ((False, sensor.linear), (True, sensor.angular)):
                if rms > 0:
                    table[:, parts.part_range(angular=angular)] = rng.standard_normal((ticks, 3)) * (rms / math.sqrt(3))
            self.noise[sensor.input] = table

    @property
    def inputs(self) -> set[str]:
        """The inputs the script writes (a scene with any has no generic hand)."""
        return ({p.input for p, _, _ in self.pushes} | {p.input for p in self.presses} | set(self.noise)
                | ({self.operator.input} if self.operator else set()) | {r.input for r in self.recorded})

    def apply(self, k: int, inputs: dict[str, np.ndarray], q=None) -> None:
        """Tick k at joints q: the active pushes and presses, the recorded inputs (a sensor's vectors turned from its
        frame into the world), and the noise, into ``inputs`` (on top of the hand's value)."""
        t = k * self.period
        if self.operator is not None:
            inputs[self.operator.input][:] = self.operator.pose(t)
        for recorded in self.recorded:
            value = recorded.at(t)
            if recorded.expressed_in is not None:
                R = self.robot.frame_pose(q, *self.sensor_frames[recorded.expressed_in])[1]
                value = (value.reshape(-1, 3) @ R.T).ravel()
            inputs[recorded.input][:] = value
        for push, part, vector in self.pushes:
            if push.active(t):
                inputs[push.input][part] += vector
        for press in self.presses:
            if press.active(t):
                inputs[press.input][0] = 1.0
        for name, table in self.noise.items():
            inputs[name] += table[k]
