"""The simulated hand: the user's force or torque on the tool, seeded and repeatable.

input(t) = aim(t) + tremor(t) + drift(t), where

- aim is ``magnitude`` times a unit vector, re-aimed every ``reaction`` seconds from what the user sees:
  push: a fixed direction; turn: a torque about a fixed axis, less its component along the guided frame's
  tool axis (a hand turning a pen around a cone tilts the pen, it does not twist it); follow: along the tangent of a curve at the
  guided frame's closest point, until the last ``STOP_DISTANCE`` (1 mm) of the curve, where the hand aims at
  the curve's end point with a magnitude falling in proportion to the distance to it (it slows down and
  stops there, and holds the frame at the end against its own tremor and drift); toward: toward a point, or the closest point of a
  plane;
- tremor is physiological tremor: per axis, four sinusoids with frequencies drawn in the 8-12 Hz band and
  random phases, scaled so that the 3-D RMS is ``tremor``;
- drift is slow wandering: per axis an Ornstein-Uhlenbeck process with time constant ``drift_time``,
  sampled exactly at the ticks, stationary 3-D RMS ``drift``.

A push acts on the force part of a wrench (the linear part of a twist), a turn on the torque part.

Without a hand in the scene, the generic hand pushes the first tracked frame (``minimize track``) along
the first world axis (x, y, z) in which the fixture lets it move (after crossing the widest tolerance,
the frame still moves at half the commanded speed or more; else the axis where it moves most), at 5 mm/s of commanded speed (a torque:
turning at 10 deg/s), with no tremor.
"""

from __future__ import annotations

import math

import numpy as np

from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.sim.geometry import Curve, Scene, unit
from vfdsl.sim.robot import LinkPose, frame_offset
from vfdsl.sim.settings import HandSettings, tracked_frame

TREMOR_COMPONENTS = 4
GENERIC_SPEED = 5e-3                 # m/s commanded by the generic hand's push
GENERIC_ANGULAR_SPEED = math.radians(10)
FREE_FRACTION = 0.5                  # an axis is free if the frame moves at least this much of what is asked
PROBE_TICKS = 400                    # at most this many ticks to find whether an axis is free
STOP_DISTANCE = 1e-3                 # m: a following hand slows down over the curve's last millimetre


class Hand:
    def __init__(self, settings: HandSettings, task: ir.Task, robot: Robot, scene: Scene, period: float,
                 ticks: int, rng: np.random.Generator):
        self.settings = settings
        self.size = task.input(settings.input).size
        self.rotational = settings.kind == "turn"
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
        part = slice(3, 6) if self.rotational and self.size == 6 else slice(0, 3)
        self._out[part] = self._aim + self.noise[k]
        return self._out

    def aim(self, q: np.ndarray) -> np.ndarray:
        s = self.settings
        if s.kind == "push":
            return self.scene.direction(_as_arg(s.direction))
        p_link, R_link = self.link_pose(q)
        p, R = p_link + R_link @ self.offset[:3, 3], R_link @ self.offset[:3, :3]
        if s.kind == "turn":
            axis = self.scene.direction(_as_arg(s.direction))
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
            toward = -normal * float(normal @ (p - point))
        else:
            toward = self.scene.point(ir.ParamRef(name=s.target)) - p
        distance = np.linalg.norm(toward)
        return toward / distance if distance > 0 else np.zeros(3)


def _as_arg(direction) -> ir.Arg:
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
    """The default hand: a push (or turn) of the first tracked frame along its first free world axis."""
    track = next((o for o in task.objectives if o.term == "track"), None)
    if track is None:
        return None
    name = track.args["input"].name
    input_type = task.input(name).type
    rotational = input_type == "torque" or (input_type in ("wrench", "twist") and "gain" not in track.args)
    gain_name, speed = ("angular_gain", GENERIC_ANGULAR_SPEED) if rotational else ("gain", GENERIC_SPEED)
    gain = track.args.get(gain_name)
    magnitude = speed / gain.value.value if gain is not None and gain.value.value > 0 else 1.0
    frame = task.frame(track.args["frame"].name)
    offset = frame_offset(frame)
    size = task.input(name).size
    # Walk long enough to cross the widest tolerance, so the last step shows whether the fixture lets it go.
    tolerances = [c.tolerance for c in task.constraints if c.tolerance is not None] or [0.0]
    ticks = min(PROBE_TICKS, 2 + math.ceil(max(tolerances) / (speed * period)))
    best, best_ratio = np.eye(3)[0], -1.0
    for axis in np.eye(3):
        value = np.zeros(size)
        value[slice(3, 6) if rotational and size == 6 else slice(0, 3)] = magnitude * axis
        inputs = {i.name: (value if i.name == name else np.zeros(i.size)) for i in task.inputs}
        q = q0.copy()
        for _ in range(ticks):
            dq = controller.step(q, inputs, dt=period)
            q = q + dq
        J = robot.frame_jacobian(q, frame.link, offset)
        ratio = axis @ (J[3:6] if rotational else J[0:3]) @ dq / (speed * period)
        if ratio >= FREE_FRACTION:
            best = axis
            break
        if ratio > best_ratio:
            best, best_ratio = axis, ratio
    return HandSettings(input=name, kind="turn" if rotational else "push", magnitude=magnitude,
                        direction=tuple(float(x) for x in unit(best)), frame=frame.name)
