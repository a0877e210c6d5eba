"""The simulated hand: the user's force or torque on the tool, seeded and repeatable.

input(t) = aim(t) + tremor(t) + drift(t), where

- aim is ``magnitude`` times a unit vector, re-aimed every ``reaction`` seconds from what the user sees:
  push: a fixed direction; turn: a torque about a fixed axis, less its component along the guided frame's
  tool axis (a hand turning a pen around a cone tilts the pen, it does not twist it); follow: along the tangent of a curve at the
  guided frame's closest point, until the last ``STOP_DISTANCE`` (1 mm) of the curve, where the hand aims at
  the curve's end point with a magnitude falling in proportion to the distance to it (it slows down and
  stops there, and holds the frame at the end against its own tremor and drift); toward: toward a point,
  or the closest point of a plane (into the plane while the frame is on it, within ``ON_PLANE``);
- tremor is physiological tremor: per axis, four sinusoids with frequencies drawn in the 8-12 Hz band and
  random phases, scaled so that the 3-D RMS is ``tremor``;
- drift is slow wandering: per axis an Ornstein-Uhlenbeck process with time constant ``drift_time``,
  sampled exactly at the ticks, stationary 3-D RMS ``drift``.

A push acts on the force part of a wrench (the linear part of a twist), a turn on the torque part.

Without a hand in the scene, :func:`generic_hand` drives the first tracked frame (``minimize track``)
where the task guides it (along its ``follows`` curve, along an ``along`` line from its first point toward
its second, else along the first world axis the fixture lets it move in), as fast as the task's speed
limits let it and at most an assumed 20 mm/s (turning: 30 deg/s), with no tremor; the run's output says
what it assumed.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.sim.geometry import Curve, Scene, unit
from vfdsl.sim.robot import LinkPose, frame_offset
from vfdsl.sim.settings import HandSettings, tracked_frame

TREMOR_COMPONENTS = 4
GENERIC_SPEED = 5e-3                 # m/s: the generic hand's probe of a direction
GENERIC_ANGULAR_SPEED = math.radians(10)
HAND_SPEED = 20e-3                   # m/s: assumed, the fastest a hand moves a tool in fine work
HAND_ANGULAR_SPEED = math.radians(30)   # rad/s: assumed, the fastest a hand turns a tool
FREE_FRACTION = 0.5                  # an axis is free if the frame moves at least this much of what is asked
PROBE_TICKS = 400                    # at most this many ticks to find whether an axis is free
STOP_DISTANCE = 1e-3                 # m: a following hand slows down over the curve's last millimetre
ON_PLANE = 1e-9
"""m: a hand pushing toward a plane keeps pushing into it while the frame is within this of it (a fixture holds the
tool on the plane to rounding, 1e-16 m on either side: the push must not flip to the other side's direction)."""


class Hand:
    def __init__(self, settings: HandSettings, task: ir.Task, robot: Robot, scene: Scene, period: float,
                 ticks: int, rng: np.random.Generator):
        self.settings = settings
        kind = INPUT_TYPES[task.input(settings.input).type]
        self.size = kind.size
        self.rotational = settings.kind == "turn"
        self.part = kind.part_range(angular=self.rotational)      # the part of the input the hand drives
        self.scene = scene
        frame_name = settings.frame or tracked_frame(task, settings.input)
        self.frame = task.frame(frame_name) if frame_name else None
        self.offset = frame_offset(self.frame) if self.frame else None
        self.link_pose = LinkPose(robot, self.frame.link) if self.frame else None
        self.curve = None
        if settings.curve:
            decl = task.param(settings.curve)
            self.curve = Curve(decl.value)
        self.every = max(1, round(settings.reaction / period))
        self.noise = tremor(rng, ticks, period, settings.tremor, settings.tremor_band) \
            + drift(rng, ticks, period, settings.drift, settings.drift_time)
        self._aim = np.zeros(3)
        self._out = np.zeros(self.size)

    def input(self, k: int, q: np.ndarray) -> np.ndarray:
        """The input at tick k, with the robot at q (what the user sees)."""
        if k % self.every == 0:
            self._aim = self.settings.magnitude * self.aim(q)
        self._out[self.part] = self._aim + self.noise[k]
        return self._out

    def aim(self, q: np.ndarray) -> np.ndarray:
        s = self.settings
        if s.kind == "push":
            return self.scene.direction(direction_arg(s.direction))
        p_link, R_link = self.link_pose(q)
        p, R = p_link + R_link @ self.offset[:3, 3], R_link @ self.offset[:3, :3]
        if s.kind == "turn":
            axis = self.scene.direction(direction_arg(s.direction))
            tool = R @ np.asarray(self.frame.tool_axis)
            tilt = axis - (axis @ tool) * tool
            return unit(tilt) if np.linalg.norm(tilt) > 1e-9 else axis
        if s.kind == "follow":
            R, _ = self.scene.to_world(s.curve)
            local = self.scene.local(ir.ParamRef(name=s.curve), p)
            (param,), _ = self.curve.closest(local, refine=False)
            if self.curve.length - param > STOP_DISTANCE:
                return R @ self.curve.tangent(param)
            to_end = np.ravel(self.curve.spline(self.curve.length) - local)
            distance = np.linalg.norm(to_end)
            return R @ to_end / STOP_DISTANCE if distance < STOP_DISTANCE else R @ to_end / distance
        decl = self.scene.task.param(s.target)
        if decl.type == "plane":
            point, normal = self.scene.plane(ir.ParamRef(name=s.target))
            side = float(normal @ (p - point))
            toward = -normal * (side if abs(side) > ON_PLANE else 1.0)
        else:
            toward = self.scene.point(ir.ParamRef(name=s.target)) - p
        distance = np.linalg.norm(toward)
        return toward / distance if distance > 0 else np.zeros(3)


def direction_arg(direction) -> ir.Arg:
    """A scene's direction (3 numbers, or the name of a direction or vector param) as the IR argument it is."""
    if isinstance(direction, str):
        return ir.ParamRef(name=direction)
    return ir.Const(value=ir.DirectionValue(xyz=list(direction)))


def tremor(rng: np.random.Generator, ticks: int, period: float, rms: float, band: tuple[float, float]) -> np.ndarray:
    """(ticks x 3) physiological tremor: sums of sinusoids in the band, 3-D RMS ``rms``."""
    frequency = rng.uniform(band[0], band[1], size=(TREMOR_COMPONENTS, 3))
    phase = rng.uniform(0.0, 2 * np.pi, size=(TREMOR_COMPONENTS, 3))
    amplitude = rms / math.sqrt(3 * TREMOR_COMPONENTS / 2)
    t = np.arange(ticks)[:, None, None] * period
    return amplitude * np.sin(2 * np.pi * frequency[None] * t + phase[None]).sum(axis=1)


def drift(rng: np.random.Generator, ticks: int, period: float, rms: float, time_constant: float) -> np.ndarray:
    """(ticks x 3) Ornstein-Uhlenbeck drift, exact at the ticks, stationary 3-D RMS ``rms``."""
    sigma = rms / math.sqrt(3)
    a = math.exp(-period / time_constant)
    steps = rng.standard_normal((ticks, 3)) * sigma
    steps[1:] *= math.sqrt(1 - a * a)
    out = np.empty((ticks, 3))
    out[0] = steps[0]
    for k in range(1, ticks):
        out[k] = a * out[k - 1] + steps[k]
    return out


def generic_hand(task: ir.Task, controller, robot: Robot, q0: np.ndarray, period: float) -> HandSettings | None:
    """The default hand, for a scene without one: it drives the first tracked frame (``minimize track``)
    where the task guides it, as fast as the task lets it, and says what it assumed (``HandSettings.assumed``).

    Where: a ``follows`` curve of the frame's link: follow it; else the first free direction among the
    lines of its ``along`` constraints (from their first point toward their second: an entry toward a
    target) and the world axes x, y, z (free: after crossing the widest tolerance the frame still moves at
    half the commanded speed or more; else the direction in which it moves most). A torque turns.

    How fast: the frame's own ``speed`` (``angular_speed``) limit; else the speed the joint speed limits
    (``joint_speed``'s fraction of the URDF's, or the URDF's) allow along that direction at the start; in
    both cases at most an assumed hand speed, ``HAND_SPEED`` (``HAND_ANGULAR_SPEED`` turning). The input's
    magnitude is that speed over the track's gain (a twist input: the speed itself times the scale)."""
    track = next((o for o in task.objectives if o.term == "track"), None)
    if track is None:
        return None
    name = track.args["input"].name
    rotational = not INPUT_TYPES[task.input(name).type].linear or "gain" not in track.args
    gain_name = "angular_gain" if rotational else "gain"
    gain = track.args.get(gain_name)
    frame = task.frame(track.args["frame"].name)
    offset = frame_offset(frame)
    scene = Scene(task)
    kind = "turn" if rotational else "push"
    curve, direction, where = None, None, ""
    if not rotational:
        curve = next((c for c in task.constraints if c.primitive == "follows" and c.frame
                      and task.frame(c.frame).link == frame.link and isinstance(c.args["curve"], ir.ParamRef)), None)
    if curve is not None:
        kind, where = "follow", f"along the curve of `{curve.frame} follows` ({_at(curve)})"
        direction = _start_tangent(task, robot, scene, frame, curve.args["curve"].name, q0)
    else:
        direction, where = _free_direction(task, controller, robot, scene, frame, name, rotational, q0, period)
    speed, why = _hand_speed(task, robot, frame, offset, direction, rotational, q0)
    if gain is not None and gain.value.value > 0:
        magnitude = speed / gain.value.value
        how = f"{why}; over the track's {gain_name}"
    else:
        magnitude, how = 1.0, f"assumed: a unit input (the track of '{name}' gives no {gain_name})"
    out = HandSettings(input=name, kind=kind, magnitude=magnitude, frame=frame.name,
                       curve=curve.args["curve"].name if curve is not None else None,
                       direction=None if curve is not None else tuple(float(x) for x in unit(direction)))
    return dataclasses.replace(out, assumed=f"the generic hand (the scene gives none): {where}; {how}")


def _start_tangent(task, robot, scene: Scene, frame, curve_name: str, q0) -> np.ndarray:
    """The world tangent of a curve at the frame's closest point at the start."""
    offset = frame_offset(frame)
    p_link, R_link = LinkPose(robot, frame.link)(q0)
    p = p_link + R_link @ offset[:3, 3]
    curve = Curve(task.param(curve_name).value)
    (s,), _ = curve.closest(scene.local(ir.ParamRef(name=curve_name), p))
    R, _ = scene.to_world(curve_name)
    return R @ curve.tangent(s)


def _free_direction(task, controller, robot, scene: Scene, frame, name: str, rotational: bool, q0,
                    period: float) -> tuple[np.ndarray, str]:
    """The first direction, among the frame's ``along`` lines and the world axes, in which the fixture lets
    the frame move (probed with the controller from the start), and what it is."""
    candidates = []
    if not rotational:
        for c in task.constraints:
            if c.primitive == "along" and c.frame and task.frame(c.frame).link == frame.link:
                _, d = scene.line(c.args["line"])
                candidates.append((np.ravel(d), f"along the line of `{c.frame} along` ({_at(c)})"))
    what = "turning about" if rotational else "along"
    candidates += [(axis, f"{what} the world's {'xyz'[i]} axis") for i, axis in enumerate(np.eye(3))]
    speed = GENERIC_ANGULAR_SPEED if rotational else GENERIC_SPEED
    kind = INPUT_TYPES[task.input(name).type]
    offset = frame_offset(frame)
    tolerances = [c.tolerance for c in task.constraints if c.tolerance is not None] or [0.0]
    ticks = min(PROBE_TICKS, 2 + math.ceil(max(tolerances) / (speed * period)))
    track = next(o for o in task.objectives if o.term == "track")
    gain = track.args.get("angular_gain" if rotational else "gain")
    magnitude = speed / gain.value.value if gain is not None and gain.value.value > 0 else 1.0
    best, best_ratio = None, -math.inf
    for axis, text in candidates:
        value = np.zeros(kind.size)
        value[kind.part_range(angular=rotational)] = magnitude * axis
        inputs = {i.name: (value if i.name == name else np.zeros(i.size)) for i in task.inputs}
        q = q0.copy()
        for _ in range(ticks):
            dq = controller.step(q, inputs, dt=period)
            q = q + dq
        J = robot.frame_jacobian(q, frame.link, offset)
        ratio = axis @ (J[3:6] if rotational else J[0:3]) @ dq / (speed * period)
        if ratio >= FREE_FRACTION:
            return axis, f"{text}, the first direction the fixture lets the frame move in"
        if ratio > best_ratio:
            best, best_ratio = (axis, f"{text}, where the fixture lets the frame move most"), ratio
    return best


def _hand_speed(task, robot: Robot, frame, offset, direction: np.ndarray, rotational: bool,
                q0: np.ndarray) -> tuple[float, str]:
    """How fast the generic hand drives the frame, and why (see :func:`generic_hand`)."""
    cap, unit_name, factor = (HAND_ANGULAR_SPEED, "deg/s", 180 / math.pi) if rotational else (HAND_SPEED, "mm/s", 1e3)
    primitive = "angular_speed" if rotational else "speed"
    scene = Scene(task)
    limits = [(float(scene.scalar(c.args["max"])), c) for c in task.constraints
              if c.primitive == primitive and c.frame == frame.name]
    if limits:
        speed, c = min(limits, key=lambda x: x[0])
        why = f"the `{c.frame} {primitive}` limit ({_at(c)}), {speed * factor:.3g} {unit_name}"
    else:
        joint = next((c for c in task.constraints if c.primitive == "joint_speed"), None)
        fraction = 1.0 if joint is None or "fraction" not in joint.args \
            else float(np.min(scene.scalar(joint.args["fraction"])))
        vmax = fraction * robot.velocity_limit
        J = robot.frame_jacobian(q0, frame.link, offset)
        dq = np.linalg.pinv(J[3:6] if rotational else J[0:3]) @ unit(direction)
        moving = np.abs(dq) > 1e-12
        speed = float(np.min(vmax[moving] / np.abs(dq[moving]))) if moving.any() else math.inf
        source = f"`joint_speed` ({_at(joint)})" if joint is not None else "the URDF's velocity limits"
        why = f"the joint speed limits of {source} allow {speed * factor:.3g} {unit_name} there"
        if not math.isfinite(speed) or speed <= 0:
            speed, why = cap, "no speed limit applies"
    if speed > cap:
        return cap, f"{why}; assumed: a hand moves it at most {cap * factor:.3g} {unit_name}"
    return speed, f"as fast as {why}"


def _at(c: ir.Constraint) -> str:
    return f"{Path(c.span.file).name}:{c.span.line}"
