"""The teleoperation readout of each tick, held by the Controller of a task with a `teleop` term: the haptic force,
the slave's set-point, following or not, the constraints that acted (vfdsl.objectives.haptics: the math), and the
readout's state between ticks (the previous depth and force of each term)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfdsl.compiler.assemble import RowLabel
from vfdsl.objectives.haptics import READOUT


@dataclass(frozen=True)
class TeleopOutput:
    """One tick's teleoperation readout (SI).

    - ``force``: the haptic force for the master (N, in the master's base frame): what the fixtures stopped of its
      command, k x its depth past them along their normals, saturated, rate-limited and ramped in at engage;
    - ``setpoint``: the teleop frame's pose after this tick's dq, [p (m); roll, pitch, yaw (rad)], for a robot driven
      by pose;
    - ``goal``: where the scaled master puts the frame's origin (m): s0 + scale R_c (m - m0), the master's ghost;
    - ``depth``: how far the master is past the rows that acted (m, in its base frame; the force is -stiffness x
      depth before its damping, saturation, ramp and rate limit);
    - ``following``: whether the master drives the slave (False while clutched, or before engage);
    - ``acting``: the constraints with rows at their bounds this tick, each named once, in row order."""

    force: np.ndarray
    setpoint: np.ndarray
    goal: np.ndarray
    depth: np.ndarray
    following: bool
    acting: tuple[str, ...]


class Teleoperation:
    """The readout function (a BufferedFunction: generated C or interpreted) and its state."""

    def __init__(self, function, labels: list[RowLabel]):
        self._function = function
        self._names = np.array([label.text(facet=False) for label in labels], dtype=object)
        *self._arguments, self._x, self._state = function.inputs
        self._outputs = dict(zip(READOUT, function.outputs))

    def update(self, data: tuple, x: np.ndarray) -> TeleopOutput:
        """The readout after a tick solved to ``x`` from the QP data arguments ``data``; advances the state."""
        for buffer, value in zip(self._arguments, data, strict=True):
            buffer[...] = value
        self._x[...] = x
        self._function.evaluate()
        out = self._outputs
        self._state[...] = out["next_state"]
        names = tuple(dict.fromkeys(self._names[out["acting"] > 0.5]))
        return TeleopOutput(out["force"].copy(), out["setpoint"].copy(), out["goal"].copy(), out["depth"].copy(),
                            bool(out["following"][0] > 0.5), names)

    def reset(self) -> None:
        """Back to the first tick's state (no previous depth or force)."""
        self._state[...] = 0.0

