"""Simulation settings: the robot's imperfections, the hand, the tracker, scripted disturbances and motions of
run-time params, and the metrics, as a simulation scene (:mod:`vfdsl.sim.scene_file`) and the command line set
them. Every value is SI. A motion is a law of time that moves one run-time param every tick
(:class:`Motion`); a disturbance an event at one time (:class:`Disturbance`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from vfdsl.sim.recording import Recording
from vfdsl.sim.operator import OperatorPath
from vfdsl import limits
from vfdsl import units as u
from vfdsl.errors import Span, VfError, suggest
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.runtime.values import ASSUMED_PERIOD

DEFAULT_DURATION = 10.0
HAND_KINDS = ("push", "turn", "follow", "toward")
DISTURBANCE_KINDS = ("move_param", "push_tool")
MOTION_KINDS = ("sine", "step", "ramp")
MAX_MOTION = 0.1
"""Largest displacement (m) a motion may give a point, curve, line, plane, pose or vector param: a breath or a
re-registration moves anatomy by millimetres, and a bigger number is a unit mistake."""
SCENE_LIMITS: dict[u.Dim, float] = {u.FORCE: 1e3, u.TORQUE: 100.0, u.SPEED: 1.0, u.ANGULAR_SPEED: 10.0,
                                    u.LENGTH: MAX_MOTION, u.ANGLE: math.pi, u.TIME: 3600.0, u.DIMENSIONLESS: 1e6}
"""The largest magnitude (SI), per dimension, of a hand's magnitude, tremor, drift, drift_time and reaction, of a
scalar param's motion, and of a disturbance's translate, by and tilt (their length): 1 kN, 100 N m, 1 m/s,
10 rad/s; 100 mm, 180 deg, 1 h, 1e6. A hand on a surgical robot pushes with tens
of newtons and moves a tool at millimetres a second: a larger number is a unit mistake (a torque in Nmm read as
N m), and an astronomic one (1e308) would overflow the run's arithmetic into non-finite metrics."""
MAX_TREMOR_FREQUENCY = 1e3
"""Hz: the highest frequency of a tremor band (physiological tremor is 8-12 Hz)."""
MAX_NOISE = 0.01
"""m: the largest tracker noise (RMS per marker; optical trackers: 0.1-0.3 mm)."""
MAX_DELAY = 10.0
"""s: the longest latency and servo lag (teleoperation over long links: up to about 2 s; with 1e308 s the robot never
moved, and the run reported perfect metrics)."""
MARKER_DISTANCES = (1e-3, 1.0)
"""m: how near and how far a tracker's second marker may be up the tool axis."""
SHOWN_IN = {u.FORCE: ("N", 1.0), u.TORQUE: ("Nmm", 1e3), u.SPEED: ("mm/s", 1e3),
            u.ANGULAR_SPEED: ("deg/s", 180 / math.pi), u.LENGTH: ("mm", 1e3), u.ANGLE: ("deg", 180 / math.pi),
            u.TIME: ("s", 1.0), u.DIMENSIONLESS: ("", 1.0)}
"""How the simulator shows a value of each dimension (a hand's magnitude, a limit): unit and factor from SI."""


def shown(value: float, dim: u.Dim) -> str:
    """``value`` (SI) in the unit SHOWN_IN gives its dimension ('0.2 mm'); in SI where that unit overflows."""
    unit, factor = SHOWN_IN[dim]
    if not math.isfinite(value * factor):
        unit, factor = u.si_formula(dim), 1.0
    return f"{value * factor:.6g} {unit}".rstrip()
RESOLUTIONS = ("off", "robot")
MOVABLE = ("point", "vector", "line", "plane", "pose", "curve")


@dataclass(frozen=True)
class HandSettings:
    """The simulated hand (see :mod:`vfdsl.sim.hand`). Vectors and magnitudes in SI input units."""

    input: str
    kind: str                                   # push | turn | follow | toward
    magnitude: float                            # N, N m (or m/s, rad/s for a twist)
    direction: tuple[float, ...] | str | None = None   # push / turn: a vector or a param name
    curve: str | None = None                    # follow: a curve param
    frame: str | None = None                    # follow / toward: the task frame the hand guides
    target: str | None = None                   # toward: a point or plane param
    tremor: float = 0.0                         # RMS, input units
    tremor_band: tuple[float, float] = (8.0, 12.0)   # Hz
    drift: float = 0.0                          # RMS, input units
    drift_time: float = 2.0                     # s
    reaction: float = 0.05                      # s between updates of the hand's aim
    assumed: str = ""                           # the generic hand: what it assumed (empty for a scene's hand)


@dataclass(frozen=True)
class Disturbance:
    at: float                                   # s
    kind: str                                   # move_param | push_tool
    param: str | None = None                    # move_param: a pose or point param
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)   # m, world axes
    tilt: tuple[float, float, float] = (0.0, 0.0, 0.0)        # rad, rotation vector (world axes) of a pose
    frame: str | None = None                    # push_tool: the task frame pushed
    by: tuple[float, float, float] = (0.0, 0.0, 0.0)          # push_tool: displacement, m
    where: Span | None = None


@dataclass(frozen=True)
class Motion:
    """A run-time param moved over time: its value plus a displacement d(t), in the param's own coordinates
    (the numbers ``Controller.step`` takes). A point or vector, the point of a line or plane, the translation
    of a pose and every point of a run-time curve move by the 3-vector d(t); a scalar param changes by the
    number d(t) (in its own dimension). Several motions of one param add up, on top of its scene value (and
    of ``move_param`` disturbances)::

        sine:  d(t) = amplitude sin(2 pi frequency t + phase)
        step:  d(t) = offset from time ``at`` on, else 0
        ramp:  d(t) = offset clip((t - start) / (end - start), 0, 1)
    """

    param: str
    kind: str                                   # sine | step | ramp
    amplitude: tuple[float, ...] = ()           # sine: m (3 numbers), or 1 number in the scalar's dimension
    frequency: float = 0.0                      # sine: Hz, below the Nyquist frequency of the period
    phase: float = 0.0                          # sine: rad
    at: float = 0.0                             # step: s
    start: float = 0.0                          # ramp: s
    end: float = 0.0                            # ramp: s, after start
    offset: tuple[float, ...] = ()              # step, ramp: like amplitude
    where: Span | None = None

    def displacement(self, t) -> np.ndarray:
        """d at the times ``t`` (N numbers, s): N x 3, or N x 1 for a scalar param."""
        t = np.asarray(t, dtype=float).reshape(-1, 1)
        if self.kind == "sine":
            return np.asarray(self.amplitude) * np.sin(2 * np.pi * self.frequency * t + self.phase)
        if self.kind == "step":
            return np.asarray(self.offset) * (t >= self.at - 1e-12)
        return np.asarray(self.offset) * np.clip((t - self.start) / (self.end - self.start), 0.0, 1.0)


def check_motions(motions: tuple[Motion, ...], period: float) -> None:
    """Refuse a periodic motion the control period cannot sample: at or above its Nyquist frequency."""
    nyquist = 0.5 / period
    for m in motions:
        if m.kind == "sine" and not m.frequency < nyquist:
            raise VfError(f"the {m.frequency:g} Hz motion of param '{m.param}' is at or above the Nyquist frequency "
                          f"of the {period * 1e3:g} ms period ({nyquist:g} Hz): the ticks cannot sample it", m.where,
                          hint="lower the frequency, or shorten the period")


PRESS_TIME = 0.1
"""s: how long a button pressed at a time (a bare time in a scene's ``buttons:``) stays down, a quick press."""


@dataclass(frozen=True)
class Push:
    """A scripted push: a constant force (``push``) or torque (``turn``) of ``magnitude`` along ``direction`` on one
    input, from ``start`` (s) until ``end`` (s, None: the end of the run), added to the hand's."""

    input: str
    magnitude: float                            # N, N m (or m/s, rad/s for a twist)
    direction: tuple[float, ...] | str          # a vector or a direction or vector param
    kind: str = "push"                          # push: the linear part; turn: the angular part
    start: float = 0.0
    end: float | None = None
    where: Span | None = None

    def active(self, t: float) -> bool:
        return in_segment(t, self.start, self.end)


@dataclass(frozen=True)
class Press:
    """A button input held down (1) from ``start`` until ``end`` (s); released (0) otherwise."""

    input: str
    start: float
    end: float
    where: Span | None = None

    def active(self, t: float) -> bool:
        return in_segment(t, self.start, self.end)


def in_segment(t: float, start: float, end: float | None) -> bool:
    """Whether time t lies in [start, end) (end None: no end), to the ticks' rounding (1e-12 s)."""
    return start - 1e-12 <= t and (end is None or t < end - 1e-12)


@dataclass(frozen=True)
class SensorNoise:
    """White noise on an input as its sensor reads it: per tick and axis Gaussian, 3-D RMS ``linear`` on the
    input's linear part and ``angular`` on its angular part (a live sensor's reading never repeats exactly)."""

    input: str
    linear: float = 0.0
    angular: float = 0.0
    where: Span | None = None


@dataclass(frozen=True)
class MetricSpec:
    """A named metric: the error of one constraint (``error_of: "tip stays_at"``), or the angle between a
    frame's tool axis and a pose param's z axis (``tilt_of: tip, normal_of: plate``)."""

    name: str
    error_of: str | None = None
    tilt_of: str | None = None
    normal_of: str | None = None
    paper: dict[str, tuple[float, float]] = field(default_factory=dict)   # source -> (mean, std), mm or deg
    where: Span | None = None


@dataclass(frozen=True)
class SimSettings:
    duration: float = DEFAULT_DURATION
    period: float = ASSUMED_PERIOD
    latency: float = 0.0
    servo_lag: float = 0.0
    resolution: str = "off"
    noise: float = 0.0                          # tracker: RMS 3-D error of one marker, m
    marker_distance: float = 0.1                # tracker: second marker this far up the tool axis, m
    trials: int = 1
    seed: int = 0
    hand: HandSettings | None = None            # None: the generic hand of the task's first tracked input
    disturbances: tuple[Disturbance, ...] = ()
    motions: tuple[Motion, ...] = ()
    metrics: tuple[MetricSpec, ...] = ()
    pushes: tuple[Push, ...] = ()               # scripted pushes over time segments
    presses: tuple[Press, ...] = ()             # button presses
    sensors: tuple[SensorNoise, ...] = ()       # inputs read with sensor noise
    operator: OperatorPath | None = None        # a master's pose over time (vfdsl.sim.operator)
    recording: Recording | None = None          # a lab's bag driving the inputs and the start (vfdsl.sim.recording)
    scene: str | None = None                    # the file these came from

    def replace(self, **changes) -> "SimSettings":
        """A copy with some settings changed, each checked like a value read from a scene."""
        for name, value in changes.items():
            check_setting(name, value)
        out = dataclasses.replace(self, **changes)
        check_motions(out.motions, out.period)
        return out

    def summary(self) -> dict:
        """The settings as plain JSON data (SI units)."""
        data = dataclasses.asdict(dataclasses.replace(self, recording=None))
        data["recording"] = None if self.recording is None else self.recording.summary
        for d in data["disturbances"] + data["motions"] + data["pushes"] + data["presses"] + data["sensors"] + \
                ((data["operator"],) if data["operator"] else ()):
            d.pop("where")
        for m in data["metrics"]:
            m.pop("where")
        return data


# Scalar settings the command line and sweeps may change, and their dimensions
SCALARS: dict[str, u.Dim] = {"duration": u.TIME, "period": u.TIME, "latency": u.TIME, "servo_lag": u.TIME,
                             "noise": u.LENGTH}


def check_setting(name: str, value, where: Span | None = None) -> None:
    """Refuse a value no simulation can use (a non-positive period, a negative latency, ...)."""
    if name in ("duration", "period"):
        if not (isinstance(value, float) and math.isfinite(value) and value > 0):
            raise VfError(f"{name} must be a positive time, got {value!r}", where)
        if name == "period" and value < limits.MIN_PERIOD:
            raise limits.exceeded(f"a period of {value:g} s is too short", limits.MIN_PERIOD, where,
                                  hint="the shortest control period is 0.01 ms (100 kHz)", unit="s")
    elif name in ("latency", "servo_lag", "noise"):
        if not (isinstance(value, float) and math.isfinite(value) and value >= 0):
            raise VfError(f"{name} must be zero or positive, got {value!r}", where)
        bare = ("bare numbers take the scene's units" if where is not None
                else "bare numbers on the command line are SI (m, s): give the unit, e.g. 0.2mm or 140ms")
        if name == "noise" and value > MAX_NOISE:
            raise VfError(f"a tracker noise of {shown(value, u.LENGTH)} RMS is beyond the {shown(MAX_NOISE, u.LENGTH)} "
                          "a simulated tracker may have", where,
                          hint=f"optical trackers: 0.1-0.3 mm; {bare}{' (units: mm?)' if where is not None else ''}")
        if name != "noise" and value > MAX_DELAY:
            raise VfError(f"a {name.replace('_', ' ')} of {value:g} s is beyond the {MAX_DELAY:g} s a simulated robot "
                          "may have", where, hint=f"teleoperation latencies are up to about 2 s, servo lags ms; {bare}")
    elif name == "resolution":
        if value not in RESOLUTIONS:
            raise VfError(f"resolution must be {' or '.join(RESOLUTIONS)}, got {value!r}", where,
                          hint="robot: the URDF sidecar's per-joint resolution")
    elif name == "trials":
        if not (isinstance(value, int) and value >= 1):
            raise VfError(f"trials must be a positive whole number, got {value!r}", where)
        if value > limits.TRIALS:
            raise limits.exceeded(f"{value:,} trials per setting", limits.TRIALS, where,
                                  hint="run fewer trials, or the run in parts with different seeds")
    elif name == "seed":
        if not (isinstance(value, int) and 0 <= value <= limits.SEED):
            raise VfError(f"seed must be a whole number from 0 to {limits.SEED:,}, got {value!r}", where)
    elif name not in ("hand", "disturbances", "motions", "metrics", "scene", "marker_distance", "pushes", "presses",
                      "sensors", "operator", "recording"):
        raise VfError(f"unknown setting '{name}'", where, hint=suggest(name, GRID_NAMES, "settings"))


def check_ticks(duration: float, period: float, where: Span | None = None, what: str = "") -> int:
    """The control ticks of one trial (duration / period, rounded), refused above ``limits.TRIAL_TICKS`` and when
    it rounds to none (a duration under half the period: a unit slip, 1e-9 for 1 s, ran one tick in silence)."""
    ticks = duration / period
    if round(ticks) < 1:
        raise VfError(f"{what}a duration of {duration:g} s is not one control tick at a {period * 1e3:g} ms period",
                      where, hint="a trial runs duration / period ticks, rounded: give a duration of at least one "
                      "period (units: 60s, 500ms)")
    if ticks > limits.TRIAL_TICKS:
        raise limits.exceeded(f"{what}{duration:g} s at a {period * 1e3:g} ms period is {ticks:,.0f} control ticks "
                              "per trial", limits.TRIAL_TICKS, where,
                              hint="shorten the duration or lengthen the period")
    return max(1, round(ticks))


GRID_NAMES = ("duration", "period", "latency", "servo_lag", "noise", "resolution")


def tracked_frame(task: ir.Task, input_name: str) -> str | None:
    """The frame that ``minimize track(frame, input)`` moves with this input, if any (outside the phases first,
    then in the phases of a procedure, in file order)."""
    for o in task.every_objective:
        if o.term == "track" and o.args["input"].name == input_name:
            return o.args["frame"].name
    return None


def hand_dimension(input_type: str, kind: str) -> u.Dim:
    """The dimension of a hand's magnitude: its input's angular part's quantity (a torque, an angular speed for a
    twist) for a turning hand, else its linear part's (a force, a speed)."""
    parts = INPUT_TYPES[input_type]
    return (parts.angular if kind == "turn" else parts.linear).dimension


def constraint_of(task: ir.Task, ref: str, where: Span | None = None) -> ir.Constraint:
    """The constraint named by ``"frame primitive"`` (``"tip stays_at"``) or ``"primitive"``; exactly one."""
    words = ref.split()
    if len(words) not in (1, 2):
        raise VfError(f"name a constraint as \"frame primitive\", like \"tip stays_at\"; got {ref!r}", where)
    frame, primitive = (None, words[0]) if len(words) == 1 else words
    found = [c for c in task.constraints if c.primitive == primitive and (frame is None or c.frame == frame)]
    if len(found) != 1:
        known = [f"{c.frame} {c.primitive}" if c.frame else c.primitive for c in task.constraints]
        problem = "no constraint" if not found else f"{len(found)} constraints"
        raise VfError(f"{problem} of task '{task.name}' match '{ref}'", where, hint=suggest(ref, known, "constraints"))
    return found[0]
