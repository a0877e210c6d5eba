"""Hands off: with zero input, a short closed loop from the start must leave the tool where it is.

The compiled controller runs for HANDS_OFF_SECONDS of the scene's period (at least MIN_TICKS ticks),
q <- q + step(q, 0), with the robot's numeric kinematics (Pinocchio) measuring every task frame's
displacement || p_t - p_0 || and rotation angle(R_0^T R_t). With zero input, tracking terms ask for no
motion (their stated rate is gain x input = 0); a frame that moves more than DRIFT_LENGTH or
DRIFT_ANGLE is reported (VF501) with the objective term that causes it: the term whose cost
w_k || E_k dq - f_k ||^2 decreases most along the loop's total motion dq (its linear part at the start,
2 w_k f_k^T E_k dq). A `distance` term pulls toward its target by design (a note); any other cause (a
redundancy term moving a tracked frame, or the constraints pulling the frame into tolerance when no
term gains) is a warning.
"""

from __future__ import annotations

import math

import numpy as np

from vfdsl.check.linearized import Linearization
from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.compiler.geometry import homogeneous
from vfdsl.ir import model as ir

HANDS_OFF_SECONDS = 0.5
MIN_TICKS = 20
DRIFT_LENGTH = 1e-5              # m
DRIFT_ANGLE = 1e-3               # rad
INTENDED = ("distance",)         # terms whose purpose is to move the frame with the hands off


def zero_inputs(task: ir.Task) -> dict[str, np.ndarray]:
    return {d.name: np.zeros(d.size) for d in task.inputs}


def run(controller, task: ir.Task, q0, ticks: int, dt: float, inputs=None, statuses: list | None = None
        ) -> np.ndarray:
    """Joint coordinates of a closed loop of ``ticks`` steps of ``dt`` (row 0 is q0) under ``inputs(t)``
    (default zero); each step's status is appended to ``statuses`` when given."""
    q = np.array(q0, dtype=float)
    trajectory = [q.copy()]
    for t in range(ticks):
        q = q + controller.step(q, zero_inputs(task) if inputs is None else inputs(t), dt=dt)
        trajectory.append(q.copy())
        if statuses is not None:
            statuses.append(controller.status)
    return np.array(trajectory)


def analyse(controller, task: ir.Task, linear: Linearization, figures: dict) -> list[Finding]:
    robot = linear.robot
    period = linear.period
    ticks = max(MIN_TICKS, math.ceil(HANDS_OFF_SECONDS / period))
    trajectory = run(controller, task, task.start, ticks, period)
    dq_total = trajectory[-1] - trajectory[0]
    findings, drift = [], {}
    for frame in task.frames:
        offset = homogeneous(frame.offset, frame.rpy)
        poses = [robot.frame_pose(q, frame.link, offset) for q in trajectory]
        p0, R0 = poses[0]
        moved = max(np.linalg.norm(p - p0) for p, _ in poses)
        turned = max(_rotation_angle(R0.T @ R) for _, R in poses)
        speeds = [np.linalg.norm(b[0] - a[0]) / period for a, b in zip(poses, poses[1:])]
        drift[frame.name] = {"moved": moved, "turned": turned, "peak_speed": max(speeds)}
        if moved <= DRIFT_LENGTH and turned <= DRIFT_ANGLE:
            continue
        cause, intended = _cause(linear, task, dq_total)
        seconds = ticks * period
        findings.append(Finding(
            "handsoff-drift", Severity.NOTE if intended else Severity.WARNING,
            f"with zero input frame '{frame.name}' moves {quantity(moved, 'length')} and turns "
            f"{quantity(turned, 'angle')} in {seconds:.3g} s ({ticks} ticks; peak speed "
            f"{quantity(max(speeds), 'speed')}); cause: {cause}", frame.span,
            None if intended else "with the hands off a tracked frame should stay still: lower that term's weight "
                                  "or check the start", f"frame {frame.name}",
            {"moved": moved, "turned": turned, "peak_speed": max(speeds), "seconds": seconds, "cause": cause}))
    figures["hands_off"] = drift
    return findings


def _cause(linear: Linearization, task: ir.Task, dq: np.ndarray) -> tuple[str, bool]:
    """The objective term that gains most along dq (and whether moving is its purpose), else the rows."""
    gains = [(2 * term.objective.weight * float(term.f @ (term.E @ dq)), term)
             for term in linear.terms(task.start)]
    gain, term = max(gains, key=lambda g: g[0], default=(0.0, None))
    if term is not None and gain > 0:
        o = term.objective
        return (f"`minimize {o.term}` at {o.span.file.rsplit('/', 1)[-1]}:{o.span.line} "
                f"(its cost falls most along the motion)", o.term in INTENDED)
    pulling = [r.constraint for r in linear.rows(task.start) if r.violation_at_rest > 0]
    if pulling:
        return ("the constraints pulling the frame into tolerance: " +
                ", ".join(f"{c.primitive} at line {c.span.line}" for c in pulling), False)
    return "no objective term or violated constraint explains it", False


def _rotation_angle(R: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2)))
