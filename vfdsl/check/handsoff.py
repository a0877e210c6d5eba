"""Hands off: with zero input, a short closed loop from the start must leave the tool where it is.

The compiled controller runs for HANDS_OFF_SECONDS of the scene's period (at least MIN_TICKS ticks),
q <- q + step(q, 0), with the robot's numeric kinematics (Pinocchio) measuring every task frame's
displacement || p_t - p_0 || and rotation angle(R_0^T R_t). With zero input, tracking terms ask for no
motion (their stated rate is gain x input = 0); a frame that moves more than DRIFT_LENGTH or
DRIFT_ANGLE is reported (VF501) with the cost that causes it: among the objective terms
w_k || E_k dq/dt - f_k ||^2 and the soft constraints' slack costs, those that fall along the loop's total
motion dq (their linear part at the start), the one at the first priority level, and within it the one
that falls most. A `distance` term pulls toward its target by design (a note); any other cause (a
redundancy term moving a tracked frame, a soft constraint pulling it into tolerance, or the hard
constraints doing so when no cost falls) is a warning.
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
    """What drives the motion dq: among the objective terms and the soft constraints' slack costs whose cost
    falls along dq, the one at the first priority level (levels are lexicographic: a later level acts only
    in the motions that leave the earlier ones optimal), and within it the one whose cost falls most;
    whether moving is its purpose; else the hard constraints pulling the frame into tolerance."""
    candidates = [(gain, priority, label, intended) for gain, priority, label, intended in _gains(linear, task, dq)
                  if gain > 0]
    if candidates:
        gain, priority, label, intended = min(candidates, key=lambda c: (c[1], -c[0]))
        return f"{label} (priority {priority}; its cost falls most along the motion)", intended
    pulling = [r.constraint for r in linear.rows(task.start) if r.violation_at_rest > 0 and not r.constraint.soft]
    if pulling:
        return ("the constraints pulling the frame into tolerance: " +
                ", ".join(f"{c.primitive} at line {c.span.line}" for c in pulling), False)
    return "no objective term or violated constraint explains it", False


def _gains(linear: Linearization, task: ir.Task, dq: np.ndarray):
    """(the linear decrease of each cost along dq, its priority level, its name, intended) in rate units:
    a term w || E dq/dt - f ||^2 falls by 2 w f' E dq / dt; a soft constraint's slack cost w (s/dt)^2, with
    s the largest violation of its rows at rest, falls by 2 w (s/dt) (a dq/dt) along its most violated row."""
    dt = linear.period
    for term in linear.terms(task.start):
        o = term.objective
        yield (2 * o.weight * float(term.f @ (term.E @ dq)) / dt, o.priority,
               f"`minimize {o.term}` at {_at(o.span)}", o.term in INTENDED)
    for r in linear.rows(task.start):
        c = r.constraint
        if not c.soft or not len(r.A):
            continue
        violations = np.concatenate([r.lb, -r.ub])
        k = int(np.argmax(violations))
        s = float(violations[k])
        if not s > 0 or not np.isfinite(s):
            continue
        rate = float(r.A[k % len(r.A)] @ dq) * (1 if k < len(r.lb) else -1)
        yield (2 * (c.weight or 1.0) * (s / dt) * (rate / dt), c.priority or 1,
               f"soft `{c.primitive}` at {_at(c.span)}", False)


def _at(span) -> str:
    return f"{span.file.rsplit('/', 1)[-1]}:{span.line}"


def _rotation_angle(R: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2)))
