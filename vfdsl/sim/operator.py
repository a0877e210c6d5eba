"""A simulated operator at a teleoperation master (a scene's ``operator:``), and what a teleoperated run measured.

    operator:                  # the master's pose over time, linear between waypoints (bare numbers: the scene's units)
      input: master            # a pose input of the task
      path:
        - {at: 0 s, position: [0, 0, 0]}
        - {at: 2 s, position: [10, 0, -30], rpy: [0, 0, 20]}     # rpy: roll, pitch, yaw (default 0)
    buttons:
      clutch: {from: 3 s, to: 4 s}     # the clutch pressed while the master is brought back (vfdsl.sim.scripted)

Before the first waypoint the master rests at it, after the last it stays at the last. Angles are interpolated
componentwise (the waypoints of a path are close enough for that).

:class:`TeleopRecord` keeps each tick's readout (``Controller.teleop``) and sums it up: the slave's error to the
scaled command where no fixture acts (|goal - set-point|: the tracking lag, docs/language.md), the haptic force in
free motion and where fixtures act, and how long the master was followed and how long fixtures acted meanwhile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import yaml

from vfdsl import units as u
from vfdsl.errors import Span, VfError, suggest

OPERATOR_KEYS = ("input", "path")
WAYPOINT_KEYS = ("at", "position", "rpy")


@dataclass(frozen=True)
class OperatorPath:
    """The master's pose [p (m); roll, pitch, yaw (rad)] at each waypoint time (s, increasing)."""

    input: str
    times: tuple[float, ...]
    poses: tuple[tuple[float, ...], ...]
    where: Span | None = None

    def pose(self, t: float) -> np.ndarray:
        """The master's pose at time t (linear between waypoints, held outside them)."""
        table = np.array(self.poses)
        return np.array([np.interp(t, self.times, table[:, i]) for i in range(6)])


def read_operator(reader, node: yaml.Node) -> OperatorPath:
    """The scene's ``operator:``, each waypoint checked at its line (``reader``: the scene reader)."""
    fields = reader.mapping(node, OPERATOR_KEYS, "the operator")
    for key in OPERATOR_KEYS:
        if key not in fields:
            raise VfError(f"the operator needs '{key}'", reader.pos(node),
                          hint="operator: {input: master, path: [{at: 0 s, position: [0, 0, 0]}, ...]}", code="E602")
    name = reader.text(fields["input"][1], "input")
    poses = [i.name for i in reader.task.inputs if i.type == "pose"]
    if name not in poses:
        kind = next((f"a {i.type}" for i in reader.task.inputs if i.name == name), "not an input of the task")
        raise VfError(f"the operator moves a master's pose; '{name}' is {kind}", reader.pos(fields["input"][1]),
                      hint=suggest(name, poses, "pose inputs"), code="E602")
    path = fields["path"][1]
    if not isinstance(path, yaml.SequenceNode) or not path.value:
        raise VfError("the operator's path is a list of waypoints like {at: 1 s, position: [0, 0, -10]}",
                      reader.pos(path), code="E602")
    times, rows = [], []
    for item in path.value:
        waypoint = reader.mapping(item, WAYPOINT_KEYS, "a waypoint")
        for key in ("at", "position"):
            if key not in waypoint:
                raise VfError(f"a waypoint needs '{key}'", reader.pos(item), code="E602")
        t = reader.scalar(waypoint["at"][1], u.TIME)
        if times and not t > times[-1]:
            raise VfError(f"waypoint times must increase: {t:g} s comes after {times[-1]:g} s",
                          reader.pos(waypoint["at"][1]), code="E602")
        if t < 0:
            raise VfError(f"a waypoint's time must be zero or positive, got {t:g} s", reader.pos(waypoint["at"][1]),
                          code="E602")
        position = reader.vector(waypoint["position"][1], u.LENGTH)
        rpy = reader.vector(waypoint["rpy"][1], u.ANGLE) if "rpy" in waypoint else (0.0, 0.0, 0.0)
        for value, dim, what in ((position, u.LENGTH, "a master position"), (rpy, u.ANGLE, "a master angle")):
            for x in value:
                reader.plausible(abs(x), dim, item, what)
        times.append(t)
        rows.append(tuple(position) + tuple(rpy))
    return OperatorPath(input=name, times=tuple(times), poses=tuple(rows), where=reader.pos(node))


class TeleopRecord:
    """Each tick's teleoperation readout, in arrays allocated once, and its summary."""

    def __init__(self, ticks: int):
        self.force = np.zeros((ticks, 3))
        self.error = np.zeros(ticks)
        self.following = np.zeros(ticks, dtype=bool)
        self.acting = np.zeros(ticks, dtype=bool)

    def tick(self, k: int, ctrl) -> None:
        out = ctrl.teleop
        self.force[k] = out.force
        self.error[k] = np.linalg.norm(out.goal - out.setpoint[:3])
        self.following[k] = out.following
        self.acting[k] = bool(out.acting)

    def columns(self) -> dict:
        """The trace's teleoperation columns (vfdsl.sim.trace)."""
        return {"haptic_x_N": self.force[:, 0], "haptic_y_N": self.force[:, 1], "haptic_z_N": self.force[:, 2],
                "following": self.following.astype(int), "fixture_acting": self.acting.astype(int),
                "command_error_m": self.error}

    def series(self) -> dict:
        """For the plot: the haptic force's magnitude (N), the error to the command (m; NaN where the master is not
        followed: there is no command), fixtures acting."""
        return {"force": np.linalg.norm(self.force, axis=1), "error": np.where(self.following, self.error, np.nan),
                "acting": self.following & self.acting}

    def summary(self, period: float) -> dict:
        """Tracking error where the master is followed and no fixture acts (mean, max, m), haptic force there and
        where fixtures act (max, N), and the time followed and the time fixtures acted while followed (s)."""
        magnitude = np.linalg.norm(self.force, axis=1)
        free = self.following & ~self.acting
        acting = self.following & self.acting

        def worst(values, mask):
            return float(values[mask].max()) if mask.any() else None
        return {"following_s": float(self.following.sum() * period), "acting_s": float(acting.sum() * period),
                "command_error_mean_m": float(self.error[free].mean()) if free.any() else None,
                "command_error_max_m": worst(self.error, free),
                "force_free_max_N": worst(magnitude, free), "force_acting_max_N": worst(magnitude, acting),
                "force_max_N": float(magnitude.max(initial=0.0))}


def teleop_table(doc: dict) -> str:
    """The teleoperation part of a report: per trial the figures of :meth:`TeleopRecord.summary`."""
    lines = [f"{'trial':>5} {'followed (s)':>12} {'fixture acted (s)':>17} {'error to command (mm) mean/max':>31} "
             f"{'force free (N)':>14} {'force acting (N)':>16}"]

    def mm(x):
        return "-" if x is None else f"{1e3 * x:.3f}"

    def newton(x):
        return "-" if x is None else f"{x:.3f}"
    for row in doc["teleop"]:
        lines.append(f"{row['trial']:>5} {row['following_s']:>12.3f} {row['acting_s']:>17.3f} "
                     f"{mm(row['command_error_mean_m']) + ' / ' + mm(row['command_error_max_m']):>31} "
                     f"{newton(row['force_free_max_N']):>14} {newton(row['force_acting_max_N']):>16}")
    return "\n".join(lines)
