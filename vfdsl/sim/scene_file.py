"""Simulation scenes: the YAML file of a task's simulation settings (:mod:`vfdsl.sim.settings`).

They come from a simulation scene (``<task>.sim.yaml`` next to the task file, or ``--scene FILE``), and
the command line overrides the scalar ones. Every value is SI inside; bare numbers in the file take its
``units`` (default m, rad, s, N). A mistake is a :class:`VfError` at the file, line and column::

    units: mm, deg
    duration: 60 s
    period: 10 ms              # default: the task scene's period, else 10 ms
    latency: 0 ms              # command latency: a command reaches the joints this long after its tick
    servo_lag: 0 ms            # first-order time constant of the joint servos
    resolution: off            # off, or robot: the URDF sidecar's per-joint resolution (SHR: 10 um)
    trials: 5
    seed: 1
    tracker: {noise: 0.2 mm, marker_distance: 100 mm}   # optical tracker: RMS 3-D noise per marker
    hand:                      # the user's input; see vfdsl.sim.hand for the kinds
      input: tau
      kind: turn               # push | turn | follow | toward
      axis: [0, -0.2, 1]       # or the name of a direction param
      magnitude: 0.3 Nmm
      tremor: 0.05 Nmm         # RMS of the 8-12 Hz physiological tremor
      drift: 0.05 Nmm          # RMS of the slow drift (time constant drift_time, default 2 s)
    disturbances:              # one-off events, at a time
      - {at: 10 s, kind: move_param, param: plate, translate: [0, 2, 0], tilt: [3, 0, 0]}
      - {at: 20 s, kind: push_tool, frame: tip, by: [0.5, 0, 0]}
    motions:                   # run-time params moved over time (breathing, re-registration, a drifting target)
      - {param: vessel, kind: sine, amplitude: [0, 0, 2], frequency: 0.25 Hz, phase: 0 deg}
      - {param: entry, kind: step, at: 5 s, offset: [1, 0, 0]}
      - {param: target, kind: ramp, start: 2 s, end: 4 s, offset: [0, 0.5, 0]}
      - {param: margin, kind: sine, amplitude: 0.5, frequency: 1 Hz}   # a scalar: one number of its dimension
    metrics:                   # names for the errors of the task's constraints, with the paper's figures
      pivot_error: {error_of: tip stays_at, paper: {encoders: [0.01, 0.01], tracker: [0.23, 0.11]}}
      tool_tilt: {tilt_of: tip, normal_of: plate}
    pushes:                    # scripted forces and torques over time segments (vfdsl.sim.scripted)
      - {input: hand, from: 3 s, to: 6 s, magnitude: 3 N, direction: [0, 0, -1]}
    buttons: {go: {from: 2 s, to: 2.1 s}}    # button inputs' presses
    sensors: {hand: {noise: 0.02 N}}          # an input's sensor noise (3-D RMS)
    operator:                  # a teleoperation master's pose over time (vfdsl.sim.operator)
      input: master
      path: [{at: 0 s, position: [0, 0, 0]}, {at: 2 s, position: [10, 0, -30], rpy: [0, 0, 20]}]
    recording:                 # a lab's bag: inputs from topics, the start from joint states (vfdsl.sim.recording)
      bag: runs/lab.mcap
      inputs: {tau: /ft_sensor/wrench}
      start: /joint_states

Motions and disturbances are separate lists: a disturbance is an event (the world changes once, at ``at``);
a motion is a law of time that moves one run-time param every tick (:class:`Motion`). A motion displaces
the param in its own coordinates (the numbers ``Controller.step`` takes): a point or vector, the point of a
line or plane, a pose's translation, and every point of a ``curve(..., runtime = true)`` by a 3-vector of
lengths; a scalar param (a length, an angle, ...) by one number of its dimension. Several motions of one
param add up, on top of its scene value and of ``move_param`` disturbances. ``sine`` takes an amplitude, a
frequency in Hz (positive, below the Nyquist frequency 1 / (2 period), checked again when ``--period``
changes the period) and an optional phase; ``step`` an offset from time ``at`` on; ``ramp`` an offset
reached linearly from ``start`` to ``end`` and then held. A motion moves only run-time params (not a curve
fixed at compile time: move the pose it is expressed in) and not directions (a direction has no position:
move the points it is derived from); a displacement is at most ``MAX_MOTION`` (100 mm). A moved value the
controller refuses at run time (a radius swung below zero) stops the run with an error at the motion's line.
The metrics score every tick against the geometry in force at that tick (:mod:`vfdsl.sim.geometry`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import yaml

from vfdsl import limits
from vfdsl import units as u
from vfdsl.errors import Span, VfError, suggest
from vfdsl.files import read_text
from vfdsl.inputs import INPUT_TYPES, described
from vfdsl.ir import model as ir
from vfdsl.passes.scene import (ValueReader, compose, node_span, read_mapping,   # the task scene's YAML reading
                                read_units)
from vfdsl.primitives.spec import SCALAR_DIMENSIONS
from vfdsl.runtime.values import ASSUMED_PERIOD
from vfdsl.sim.operator import read_operator
from vfdsl.sim.recording import read_recording
from vfdsl.sim.scripted import read_buttons, read_pushes, read_sensors
from vfdsl.sim.settings import (DISTURBANCE_KINDS, HAND_KINDS, MARKER_DISTANCES,
                                MAX_TREMOR_FREQUENCY, MOTION_KINDS, MOVABLE, SCENE_LIMITS,
                                GRID_NAMES, SCALARS, Disturbance, HandSettings, MetricSpec, Motion, SimSettings, check_motions,
                                check_setting, check_ticks, constraint_of, hand_dimension, shown,
                                tracked_frame)
from vfdsl.syntax import ast

TOP_KEYS = ("units", "duration", "period", "latency", "servo_lag", "resolution", "trials", "seed", "tracker",
             "hand", "disturbances", "motions", "metrics", "pushes", "buttons", "sensors",
             "operator", "recording")
MOTION_KEYS = {"sine": ("param", "kind", "amplitude", "frequency", "phase"),
                "step": ("param", "kind", "at", "offset"),
                "ramp": ("param", "kind", "start", "end", "offset")}
# Param types a motion displaces, and the part of their run-time value it adds to: 3 numbers (a position in
# the param's own coordinates) or 1 (a scalar). Directions have no position: a motion cannot move them.
HAND_KEYS = ("input", "kind", "magnitude", "direction", "axis", "curve", "frame", "target", "tremor",
              "tremor_band", "drift", "drift_time", "reaction")
TRACKER_KEYS = ("noise", "marker_distance")
METRIC_KEYS = ("error_of", "tilt_of", "normal_of", "paper")


def parse_setting(name: str, text: str) -> object:
    """A command-line value: ``"150ms"``, ``"0.2 mm"``, ``"robot"``; bare numbers are SI."""
    if name not in GRID_NAMES:
        raise VfError(f"unknown setting '{name}'", hint=suggest(name, GRID_NAMES, "settings"))
    if name == "resolution":
        value = text.strip()
    else:
        node = yaml.compose(f"'{text.strip()}'") if text.strip() else None
        if node is None:
            raise VfError(f"{name}: expected a value like 10ms, got nothing")
        where = "<command line>"
        quantity = ValueReader(where).read(node)
        value = _si(quantity, SCALARS[name], u.DefaultUnits())
    check_setting(name, value)
    return value


def default_scene(task_file: str | Path) -> Path | None:
    """``<task>.sim.yaml`` next to the task file, if there is one."""
    path = Path(task_file).with_suffix(".sim.yaml")
    return path if path.is_file() else None


def load_settings(task: ir.Task, scene: str | Path | None) -> SimSettings:
    """The settings of ``scene`` (a ``.sim.yaml`` file), checked against ``task``; defaults without one."""
    base = SimSettings(period=task.scene.period or ASSUMED_PERIOD)
    if scene is None:
        return base
    path = Path(scene)
    text = read_text(path, "simulation scene")
    try:
        return _Reader(task, str(path)).settings(compose(text, path), base)
    except VfError as err:                      # a mistake in the scene file: E602 unless it has a code of its own
        raise (err if err.code else err.with_code("E602")) from None


def _si(node: ast.Value, dim: u.Dim, units: u.DefaultUnits) -> float:
    if not isinstance(node, ast.Quantity):
        raise VfError(f"expected {u.describe(dim)}", node.span)
    return u.to_si(node.number, node.unit, dim, units, node.span)


class _Reader:
    """Reads one simulation scene's YAML nodes into settings, with positions for every error."""

    def __init__(self, task: ir.Task, file: str):
        self.task = task
        self.file = file
        self.units = u.DefaultUnits()

    def pos(self, node: yaml.Node) -> Span:
        return node_span(node, self.file)

    def mapping(self, node: yaml.Node, keys: tuple[str, ...], what: str) -> dict[str, tuple[yaml.Node, yaml.Node]]:
        if not isinstance(node, yaml.MappingNode):
            raise VfError(f"{what} is a mapping with keys {', '.join(keys)}", self.pos(node))
        fields = read_mapping(node, self.file)
        for key, (key_node, _) in fields.items():
            if key not in keys:
                raise VfError(f"unknown key '{key}' in {what}", self.pos(key_node), hint=suggest(key, keys, "keys"))
        return fields

    def fields(self, node: yaml.MappingNode) -> dict[str, tuple[yaml.Node, yaml.Node]]:
        return read_mapping(node, self.file)

    def aim(self, node: yaml.Node, what: str) -> tuple[float, float, float] | str:
        """A direction: 3 numbers, or the name of a direction or vector param."""
        if isinstance(node, yaml.ScalarNode):
            return self.param(node, ("direction", "vector"), what)
        return self.direction(node, what)

    def text(self, node: yaml.Node, what: str) -> str:
        if not isinstance(node, yaml.ScalarNode) or not str(node.value).strip():
            raise VfError(f"{what} is a name", self.pos(node))
        return str(node.value).strip()

    def scalar(self, node: yaml.Node, dim: u.Dim) -> float:
        return _si(ValueReader(self.file).read(node), dim, self.units)

    def vector(self, node: yaml.Node, dim: u.Dim) -> tuple[float, float, float]:
        if not isinstance(node, yaml.SequenceNode) or len(node.value) != 3:
            raise VfError(f"expected 3 numbers ({u.describe(dim)} each), like [0, 1, 0]", self.pos(node))
        return tuple(self.scalar(item, dim) for item in node.value)

    def direction(self, node: yaml.Node, what: str) -> tuple[float, float, float]:
        """A direction written as 3 numbers, scaled so its largest is +-1 (its length neither overflows nor
        underflows: [1e300, 1e300, 0] is the direction [1, 1, 0])."""
        vector = np.array(self.vector(node, u.DIMENSIONLESS))
        largest = np.abs(vector).max()
        if largest == 0:
            raise VfError(f"{what} must not be zero", self.pos(node))
        return tuple(float(x) for x in vector / largest)

    def plausible(self, value: float, dim: u.Dim, node: yaml.Node, what: str) -> None:
        """Refuse a magnitude beyond SCENE_LIMITS for its dimension, at its line."""
        limit = SCENE_LIMITS[dim]
        if abs(value) > limit:
            raise VfError(f"{what} of {shown(value, dim)} is beyond the {shown(limit, dim)} a simulation scene may give "
                          "it", self.pos(node),
                          hint="bare numbers take the scene's units (units: mm, deg?); a hand pushes with tens of "
                               "N and moves a tool at mm/s (docs/simulate.md)")

    def integer(self, node: yaml.Node, what: str) -> int:
        value = self.scalar(node, u.DIMENSIONLESS)
        if value != int(value):
            raise VfError(f"{what} must be a whole number, got {value}", self.pos(node))
        return int(value)

    def settings(self, root: yaml.Node | None, base: SimSettings) -> SimSettings:
        if root is None:
            return dataclasses.replace(base, scene=self.file)
        top = self.mapping(root, TOP_KEYS, "a simulation scene")
        if "units" in top:
            self.units = read_units(top["units"][1], self.file, self.units)
        values: dict = {"scene": self.file}
        for name, dim in SCALARS.items():
            if name in top and name != "noise":
                values[name] = self.scalar(top[name][1], dim)
        if "resolution" in top:
            values["resolution"] = self.text(top["resolution"][1], "resolution")
        for name in ("trials", "seed"):
            if name in top:
                values[name] = self.integer(top[name][1], name)
        for name, value in values.items():
            if name != "scene":
                check_setting(name, value, self.pos(top[name][1]))
        ticks_at = next((top[n][1] for n in ("duration", "period") if n in top), None)
        ticks = check_ticks(values.get("duration", base.duration), values.get("period", base.period),
                            self.pos(ticks_at) if ticks_at is not None else None)
        trials = values.get("trials", base.trials)
        if ticks * trials > limits.RUN_TICKS:
            at = top["trials"][1] if "trials" in top else ticks_at
            raise limits.exceeded(f"{trials:,} trial(s) of {ticks:,} control ticks is {ticks * trials:,} ticks",
                                  limits.RUN_TICKS, self.pos(at) if at is not None else None,
                                  hint="fewer trials, a shorter duration or a longer period")
        if "tracker" in top:
            tracker = self.mapping(top["tracker"][1], TRACKER_KEYS, "tracker")
            if "noise" in tracker:
                values["noise"] = self.scalar(tracker["noise"][1], u.LENGTH)
                check_setting("noise", values["noise"], self.pos(tracker["noise"][1]))
            if "marker_distance" in tracker:
                values["marker_distance"] = self.scalar(tracker["marker_distance"][1], u.LENGTH)
                near, far = MARKER_DISTANCES
                if not near <= values["marker_distance"] <= far:
                    raise VfError(f"marker_distance must be from {shown(near, u.LENGTH)} to {shown(far, u.LENGTH)}, got "
                                  f"{shown(values['marker_distance'], u.LENGTH)}", self.pos(tracker["marker_distance"][1]))
        if "hand" in top:
            values["hand"] = self.hand(top["hand"][1])
        if "disturbances" in top:
            node = top["disturbances"][1]
            if not isinstance(node, yaml.SequenceNode):
                raise VfError("disturbances is a list of mappings like {at: 5 s, kind: push_tool, ...}",
                              self.pos(node))
            values["disturbances"] = tuple(self.disturbance(item) for item in node.value)
        if "motions" in top:
            node = top["motions"][1]
            if not isinstance(node, yaml.SequenceNode):
                raise VfError("motions is a list of mappings like {param: vessel, kind: sine, amplitude: [0, 0, 2], "
                              "frequency: 0.25 Hz}", self.pos(node))
            values["motions"] = tuple(self.motion(item) for item in node.value)
            check_motions(values["motions"], values.get("period", base.period))
        if "metrics" in top:
            node = top["metrics"][1]
            if not isinstance(node, yaml.MappingNode):
                raise VfError("metrics is a mapping from names to {error_of: ...} or {tilt_of: ...}", self.pos(node))
            values["metrics"] = tuple(self.metric(name, key, value)
                                      for name, (key, value) in read_mapping(node, self.file).items())
        for key, read, name in (("pushes", read_pushes, "pushes"), ("buttons", read_buttons, "presses"),
                                ("sensors", read_sensors, "sensors"), ("operator", read_operator, "operator"),
                                ("recording", read_recording, "recording")):
            if key in top:
                values[name] = read(self, top[key][1])
        return dataclasses.replace(base, **values)

    # ---------------------------------------------------------------------------------------- hand
    def hand(self, node: yaml.Node) -> HandSettings:
        fields = self.mapping(node, HAND_KEYS, "hand")
        for key in ("input", "kind", "magnitude"):
            if key not in fields:
                raise VfError(f"the hand needs '{key}'", self.pos(node))
        name = self.text(fields["input"][1], "input")
        inputs = {i.name: i for i in self.task.inputs}
        if name not in inputs:
            raise VfError(f"the hand drives input '{name}', which task '{self.task.name}' does not declare",
                          self.pos(fields["input"][1]), hint=suggest(name, inputs, "inputs"))
        kind = self.text(fields["kind"][1], "kind")
        if kind not in HAND_KINDS:
            raise VfError(f"unknown hand kind '{kind}'", self.pos(fields["kind"][1]),
                          hint=suggest(kind, HAND_KINDS, "kinds"))
        input_type = inputs[name].type
        if kind == "turn" and not INPUT_TYPES[input_type].angular:
            raise VfError(f"a turning hand needs {described(lambda t: t.angular)}; '{name}' is a {input_type}",
                          self.pos(fields["kind"][1]), hint="use kind: push, follow or toward")
        if kind != "turn" and not INPUT_TYPES[input_type].linear:
            raise VfError(f"a {kind} hand needs {described(lambda t: t.linear)}; '{name}' is a {input_type}",
                          self.pos(fields["kind"][1]), hint="use kind: turn")
        dim = hand_dimension(input_type, kind)
        out: dict = {"input": name, "kind": kind, "magnitude": self.scalar(fields["magnitude"][1], dim)}
        for key in ("tremor", "drift"):
            if key in fields:
                out[key] = self.scalar(fields[key][1], dim)
        for key in ("magnitude", "tremor", "drift"):
            if key in out and out[key] < 0:
                raise VfError(f"{key} must be zero or positive", self.pos(fields[key][1]))
            if key in out:
                self.plausible(out[key], dim, fields[key][1], f"a hand's {key}")
        if "tremor_band" in fields:
            band_node = fields["tremor_band"][1]
            if not isinstance(band_node, yaml.SequenceNode) or len(band_node.value) != 2:
                raise VfError("tremor_band is [low, high] in Hz, like [8, 12]", self.pos(band_node))
            band = tuple(self.scalar(n, u.DIMENSIONLESS) for n in band_node.value)
            if not 0 < band[0] <= band[1]:
                raise VfError("tremor_band needs 0 < low <= high (Hz)", self.pos(band_node))
            if band[1] > MAX_TREMOR_FREQUENCY:
                raise VfError(f"a tremor band up to {band[1]:.6g} Hz is beyond the {MAX_TREMOR_FREQUENCY:g} Hz a "
                              "simulated tremor may reach", self.pos(band_node),
                              hint="physiological tremor is 8-12 Hz")
            out["tremor_band"] = band
        for key in ("drift_time", "reaction"):
            if key in fields:
                out[key] = self.scalar(fields[key][1], u.TIME)
                if out[key] <= 0:
                    raise VfError(f"{key} must be a positive time", self.pos(fields[key][1]))
                self.plausible(out[key], u.TIME, fields[key][1], f"a hand's {key}")
        for key in ("direction", "axis"):
            if key in fields:
                out["direction"] = self.aim(fields[key][1], key)
        if "curve" in fields:
            out["curve"] = self.param(fields["curve"][1], ("curve",), "curve")
        if "target" in fields:
            out["target"] = self.param(fields["target"][1], ("point", "plane"), "target")
        if "frame" in fields:
            out["frame"] = self.frame(fields["frame"][1])
        if kind != "push" and "frame" not in out and tracked_frame(self.task, name) is None:
            raise VfError(f"a {kind} hand needs 'frame': no `minimize track(...)` of task '{self.task.name}' "
                          f"says which frame input '{name}' moves", self.pos(node))
        needs = {"push": ("direction",), "turn": ("direction",), "follow": ("curve",), "toward": ("target",)}[kind]
        for key in needs:
            if key not in out:
                raise VfError(f"a {kind} hand needs '{'axis' if kind == 'turn' else key}'", self.pos(node))
        return HandSettings(**out)

    def param(self, node: yaml.Node, types: tuple[str, ...], what: str) -> str:
        name = self.text(node, what)
        params = {p.name: p for p in self.task.params}
        if name not in params:
            raise VfError(f"unknown param '{name}'", self.pos(node), hint=suggest(name, params, "params"))
        if params[name].type not in types:
            raise VfError(f"{what} must be a {' or '.join(types)} param; '{name}' is a {params[name].type}",
                          self.pos(node))
        return name

    def frame(self, node: yaml.Node) -> str:
        name = self.text(node, "frame")
        frames = [f.name for f in self.task.frames]
        if name not in frames:
            raise VfError(f"unknown frame '{name}'", self.pos(node), hint=suggest(name, frames, "frames"))
        return name

    # -------------------------------------------------------------------------------- disturbances
    def disturbance(self, node: yaml.Node) -> Disturbance:
        fields = self.mapping(node, ("at", "kind", "param", "translate", "tilt", "frame", "by"), "a disturbance")
        for key in ("at", "kind"):
            if key not in fields:
                raise VfError(f"a disturbance needs '{key}'", self.pos(node))
        at = self.scalar(fields["at"][1], u.TIME)
        if at < 0:
            raise VfError("a disturbance time must be zero or positive", self.pos(fields["at"][1]))
        kind = self.text(fields["kind"][1], "kind")
        if kind not in DISTURBANCE_KINDS:
            raise VfError(f"unknown disturbance '{kind}'", self.pos(fields["kind"][1]),
                          hint=suggest(kind, DISTURBANCE_KINDS, "disturbances"))
        allowed = {"move_param": ("at", "kind", "param", "translate", "tilt"),
                   "push_tool": ("at", "kind", "frame", "by")}[kind]
        for key, (key_node, _) in fields.items():
            if key not in allowed:
                raise VfError(f"'{key}' does not apply to a {kind} disturbance", self.pos(key_node),
                              hint="keys: " + ", ".join(allowed))
        out: dict = {"at": at, "kind": kind, "where": self.pos(node)}
        if kind == "move_param":
            if "param" not in fields:
                raise VfError("a move_param disturbance needs 'param'", self.pos(node))
            out["param"] = self.param(fields["param"][1], ("pose", "point"), "param")
            if "translate" in fields:
                out["translate"] = self.bounded_vector(fields["translate"][1], u.LENGTH, "a move_param translation")
            if "tilt" in fields:
                if self.task.param(out["param"]).type != "pose":
                    raise VfError("only a pose param can tilt", self.pos(fields["tilt"][0]))
                out["tilt"] = self.bounded_vector(fields["tilt"][1], u.ANGLE, "a move_param tilt")
        else:
            if "frame" not in fields or "by" not in fields:
                raise VfError("a push_tool disturbance needs 'frame' and 'by'", self.pos(node))
            out["frame"] = self.frame(fields["frame"][1])
            out["by"] = self.bounded_vector(fields["by"][1], u.LENGTH, "a push_tool displacement")
        return Disturbance(**out)

    # ------------------------------------------------------------------------------------- motions
    def motion(self, node: yaml.Node) -> Motion:
        keys = tuple(dict.fromkeys(k for ks in MOTION_KEYS.values() for k in ks))
        fields = self.mapping(node, keys, "a motion")
        for key in ("param", "kind"):
            if key not in fields:
                raise VfError(f"a motion needs '{key}'", self.pos(node))
        kind = self.text(fields["kind"][1], "kind")
        if kind not in MOTION_KINDS:
            raise VfError(f"unknown motion '{kind}'", self.pos(fields["kind"][1]),
                          hint=suggest(kind, MOTION_KINDS, "motions"))
        allowed = MOTION_KEYS[kind]
        for key, (key_node, _) in fields.items():
            if key not in allowed:
                raise VfError(f"'{key}' does not apply to a {kind} motion", self.pos(key_node),
                              hint="keys: " + ", ".join(allowed))
        for key in allowed:
            if key not in fields and key != "phase":
                raise VfError(f"a {kind} motion needs '{key}'", self.pos(node), hint="keys: " + ", ".join(allowed))
        name = self.moving_param(fields["param"][1])
        out: dict = {"param": name, "kind": kind, "where": self.pos(node)}
        size_key = "amplitude" if kind == "sine" else "offset"
        out[size_key] = self.displacement(fields[size_key][1], self.task.param(name))
        if kind == "sine":
            out["frequency"] = self.scalar(fields["frequency"][1], u.FREQUENCY)
            if not out["frequency"] > 0:
                raise VfError(f"frequency must be positive, got {out['frequency']:g} Hz",
                              self.pos(fields["frequency"][1]))
            if "phase" in fields:
                out["phase"] = self.scalar(fields["phase"][1], u.ANGLE)
        for key in ("at", "start", "end"):
            if key in fields:
                out[key] = self.scalar(fields[key][1], u.TIME)
                if out[key] < 0:
                    raise VfError(f"{key} must be a time >= 0", self.pos(fields[key][1]))
        if kind == "ramp" and not out["end"] > out["start"]:
            raise VfError(f"a ramp's end ({out['end']:g} s) must come after its start ({out['start']:g} s)",
                          self.pos(fields["end"][1]))
        return Motion(**out)

    def moving_param(self, node: yaml.Node) -> str:
        """A param a motion can move: run-time, and with a position (or a scalar)."""
        name = self.text(node, "param")
        params = {p.name: p for p in self.task.params}
        if name not in params:
            raise VfError(f"unknown param '{name}'", self.pos(node), hint=suggest(name, params, "params"))
        decl = params[name]
        if decl.type == "curve" and not decl.value.runtime:
            raise VfError(f"param '{name}' is a curve fixed at compile time: a motion can move only run-time params",
                          self.pos(node), hint=f"declare it `param {name} : curve(degree = {decl.value.degree}, "
                                               "runtime = true)`, or move the pose it is expressed in")
        if decl.type not in MOVABLE and decl.type not in SCALAR_DIMENSIONS:
            raise VfError(f"param '{name}' is a {decl.type}: a motion displaces positions and scalars, and a "
                          f"{decl.type} has no position", self.pos(node),
                          hint="move the points it is derived from, or the pose it is expressed in")
        return name

    def displacement(self, node: yaml.Node, decl: ir.ParamDecl) -> tuple[float, ...]:
        """A motion's amplitude or offset: 3 lengths for a param with a position, one scalar of the param's
        dimension for a scalar param; at most MAX_MOTION long."""
        if decl.type in SCALAR_DIMENSIONS:
            if isinstance(node, yaml.SequenceNode):
                raise VfError(f"param '{decl.name}' is a scalar ({decl.type}): give one number, like "
                              f"{u.example(SCALAR_DIMENSIONS[decl.type]).split('e.g. ')[-1]}", self.pos(node))
            value = self.scalar(node, SCALAR_DIMENSIONS[decl.type])
            self.plausible(value, SCALAR_DIMENSIONS[decl.type], node, f"a motion of param '{decl.name}'")
            return (value,)
        return self.bounded_vector(node, u.LENGTH, "a motion")

    def bounded_vector(self, node: yaml.Node, dim: u.Dim, what: str) -> tuple[float, float, float]:
        """3 numbers of ``dim`` whose length is at most SCENE_LIMITS[dim] (MAX_MOTION for a length)."""
        vector = self.vector(node, dim)
        limit = SCENE_LIMITS[dim]
        largest = float(np.abs(vector).max())
        with np.errstate(over="ignore"):           # (|vector| = largest * |vector / largest| overflows only past 1e308)
            length = largest * float(np.linalg.norm(np.array(vector) / largest)) if largest > 0 else 0.0
        if not length <= limit:
            raise VfError(f"{what} of {shown(length, dim)} is beyond the {shown(limit, dim)} a simulation scene may "
                          "give it", self.pos(node), hint="bare numbers take the scene's units (units: mm, deg?)")
        return vector

    # ------------------------------------------------------------------------------------- metrics
    def metric(self, name: str, key_node: yaml.Node, node: yaml.Node) -> MetricSpec:
        fields = self.mapping(node, METRIC_KEYS, f"metric '{name}'")
        out: dict = {"name": name, "where": self.pos(key_node)}
        if ("error_of" in fields) == ("tilt_of" in fields):
            raise VfError(f"metric '{name}' needs exactly one of error_of (\"frame primitive\") or tilt_of (a frame)",
                          self.pos(node))
        if "error_of" in fields:
            out["error_of"] = self.text(fields["error_of"][1], "error_of")
            constraint_of(self.task, out["error_of"], self.pos(fields["error_of"][1]))
        else:
            out["tilt_of"] = self.frame(fields["tilt_of"][1])
            if "normal_of" not in fields:
                raise VfError(f"metric '{name}' needs normal_of: a pose param", self.pos(node))
            out["normal_of"] = self.param(fields["normal_of"][1], ("pose",), "normal_of")
        if "paper" in fields:
            paper = {}
            for source, (k, v) in self.mapping(fields["paper"][1], ("encoders", "tracker"), "paper").items():
                if not isinstance(v, yaml.SequenceNode) or len(v.value) != 2:
                    raise VfError("the paper's figure is [mean, std] in mm or deg", self.pos(v))
                paper[source] = tuple(float(self.scalar(n, u.DIMENSIONLESS)) for n in v.value)
            out["paper"] = paper
        return MetricSpec(**out)
