"""Residuals at the start: how far each hard constraint is from holding before anything moves.

The rows measure the state at rest (dq = 0): a constraint's error is ``gauge = eps + max(lb, -ub)`` over
its rows, i.e. max_i u_i . delta for a polytope (between cos(pi/n) ||delta|| and ||delta||), the signed
depth for a plane. Direction constraints linearize with a cross product, whose length is sin(angle) up to
90 deg, continued as 2 - sin(angle) beyond (docs/primitives.md, note 8): not the angle (a tool axis 177 deg off
measures 1.95). For those the true angle is measured instead, the ``true_angle`` of the
primitive's spec (keeps_direction: angle(l_t, l_d); cone: | angle(l_t, l_a) - gamma |; tilt_at_most:
max(0, angle(l_t, a) - gamma); rotates_around: | asin(l_t . w) |), and where the spec says
``error_is_distance`` (stays_at, within_distance, within_sphere) the distance || p - P || to its
``reference_point`` itself.

A constraint whose error exceeds its tolerance is VF402 (warning); beyond FAR x the tolerance (or
FAR_ABSOLUTE for exact rows without one) it is VF401 (error), with the likely cause: an opposite
direction (angle near 180 deg), a wrong frame axis (near 90 deg), a wrong unit (the reference read in mm
instead of m or the reverse, or an angle in rad instead of deg, would fit), else the start or the reference.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from vfdsl.check.linearized import ConstraintRows, Linearization
from vfdsl.ir.constraints import subject, where
from vfdsl.primitives.bounds import stated_size
from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.compiler.context import Context
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS

FAR = 10.0                       # x the tolerance: "far outside"
FAR_ABSOLUTE = 1e-4              # m or rad, for rows without a tolerance (a half-space)
UNIT_FACTORS = (1e3, 1e-3)       # mm <-> m slips


class Residuals:
    """Numeric true-angle errors and reference points of a task's constraints, at any q."""

    def __init__(self, task: ir.Task, context: Context):
        self.context = context
        symbols = [context.q, context.p]
        specs = [CONSTRAINTS[c.primitive] for c in task.constraints]
        self._angles = {i: ca.Function("angle", symbols, [specs[i].true_angle(c, context)])
                        for i, c in enumerate(task.constraints) if specs[i].true_angle}
        self._axes = {i: ca.Function("axes", symbols, [context.frame(c.frame).axis,
                                                        context.direction(c.args["axis"] if "axis" in c.args
                                                                          else c.args["direction"])])
                      for i, c in enumerate(task.constraints) if specs[i].true_angle}
        self._points = {i: ca.Function("point", symbols, [context.frame(c.frame).p,
                                                         context.point(c.args[specs[i].reference_point])])
                        for i, c in enumerate(task.constraints) if specs[i].reference_point}

    def true_angle(self, index: int, q, p) -> float | None:
        f = self._angles.get(index)
        return None if f is None else float(f(q, p))

    def between_axes(self, index: int, q, p) -> float:
        """The angle between the tool axis and the constraint's direction (or axis)."""
        l_t, l_d = (np.array(v).ravel() for v in self._axes[index](q, p))
        return math.atan2(np.linalg.norm(np.cross(l_t, l_d)), float(l_t @ l_d))

    def frame_and_reference(self, index: int, q, p) -> tuple[np.ndarray, np.ndarray] | None:
        f = self._points.get(index)
        return None if f is None else tuple(np.array(v).ravel() for v in f(q, p))


def _error(task: ir.Task, r: ConstraintRows, residuals: Residuals, q, p):
    """(kind, stated limit, error, true angle or None) of a constraint at q; None when it has no such error."""
    c = r.constraint
    stated = stated_size(c, task)
    if r.bounds or not len(r.A) or (stated is not None and stated[0] not in ("length", "angle")):
        return None
    spec = CONSTRAINTS[c.primitive]
    kind, limit = stated if stated is not None else (("angle" if spec.true_angle else "length"), 0.0)
    angle = residuals.true_angle(r.index, q, p)
    error = angle if angle is not None else limit + r.violation_at_rest
    if spec.error_is_distance:
        frame, reference = residuals.frame_and_reference(r.index, q, p)
        error = float(np.linalg.norm(frame - reference))
    return kind, limit, error, angle


def _outside(error: float, limit: float) -> bool:
    return error > limit * (1 + 1e-6) + 1e-12


def analyse(task: ir.Task, linear: Linearization, rows: list[ConstraintRows], q) -> list[Finding]:
    residuals = Residuals(task, linear.context)
    p = linear.default_params
    findings = []
    for r in rows:
        c = r.constraint
        measured = None if c.soft else _error(task, r, residuals, q, p)
        if measured is None:
            continue
        kind, limit, error, angle = measured
        if not _outside(error, limit):
            continue
        far = error > (FAR * limit if limit > 0 else FAR_ABSOLUTE)
        cause = _likely_cause(r.index, c, residuals, q, p, error) if far else None
        what = f"{quantity(limit, kind)} tolerance" if limit > 0 else "boundary"
        message = (f"at the start the error is {quantity(error, kind)}, "
                   f"{error / limit:.3g} x its {what}" if limit > 0 else
                   f"at the start the frame is {quantity(error, kind)} on the wrong side of its {what}")
        if CONSTRAINTS[c.primitive].angle_rows == "cos":
            message += f" (the row, which measures cos gamma - cos of the angle, sees {r.violation_at_rest:.3g})"
        elif angle is not None:
            message += f" (the rows, which measure sin of the angle, see {quantity(limit + r.violation_at_rest, kind)})"
        data = {"error": error, "limit": limit, "rows_error": limit + r.violation_at_rest, "cause": cause}
        if far:
            findings.append(Finding("residual-far", Severity.ERROR, f"{message}; likely cause: {cause}", c.span,
                                    "fix the direction, axis or unit named above, or the scene's start",
                                    subject(c), data))
        else:
            findings.append(Finding("residual-outside", Severity.WARNING,
                                    f"{message}; the first ticks pull it back", c.span,
                                    "start inside the tolerance (the scene's start or the reference)",
                                    subject(c), data))
    return findings


def _likely_cause(index: int, c: ir.Constraint, residuals: Residuals, q, p, error: float) -> str:
    """The likely cause of an error far beyond the tolerance: for a true angle, by the angle the spec's
    ``kept_angle`` says the tool axis keeps; for a reference point, a unit slip if one would fit."""
    spec = CONSTRAINTS[c.primitive]
    if spec.true_angle:
        theta = residuals.between_axes(index, q, p)
        between = math.degrees(theta)
        if spec.kept_angle == 0.0 and between > 150:
            return (f"opposite direction: the tool axis points {between:.1f} deg away from the direction "
                    f"(given the insertion direction instead of the tool axis?)")
        if isinstance(spec.kept_angle, str):
            gamma = _gamma(c, spec.kept_angle, residuals, p)
            if abs(theta - (math.pi - gamma)) < abs(theta - gamma):
                return (f"opposite direction: the tool axis is {between:.1f} deg from the cone axis, "
                        f"{math.degrees(math.pi - theta):.1f} deg from its opposite: the axis points the other way?")
            if abs(theta - math.radians(gamma)) < 0.1 * error:
                return f"wrong unit: the half-angle reads as {gamma:g} rad; was {gamma:g} deg meant?"
        if 60 < between < 120:
            return f"wrong frame axis: the tool axis is {between:.1f} deg from the direction (the frame's axis?)"
        return f"the start configuration or the direction: the tool axis is {between:.1f} deg from it"
    points = residuals.frame_and_reference(index, q, p)
    if points is not None:
        frame, reference = points
        distance = np.linalg.norm(frame - reference)
        for factor in UNIT_FACTORS:
            if np.linalg.norm(frame - factor * reference) < 0.1 * distance:
                unit = "m instead of mm" if factor > 1 else "mm instead of m"
                return (f"wrong unit: the reference {np.round(reference * 1e3, 3).tolist()} mm is {distance * 1e3:.4g} mm "
                        f"from the frame, but x{factor:g} it would fit (written in {unit}?)")
        return (f"the start configuration or the reference: the frame is at {np.round(frame * 1e3, 3).tolist()} mm, "
                f"the reference at {np.round(reference * 1e3, 3).tolist()} mm")
    return "the start configuration or the reference"


def _gamma(c: ir.Constraint, name: str, residuals: Residuals, p) -> float:
    """The angle argument ``name`` of ``c`` at params p (rad)."""
    return float(ca.Function("gamma", [residuals.context.p], [residuals.context.scalar(c.args[name])])(p))


def soft_at_start(task: ir.Task, linear: Linearization, rows: list[ConstraintRows], q, nq: int,
                  figures: dict) -> list[Finding]:
    """VF403: a soft constraint that does not hold at the start, with its error there; and whether any
    motion within the joint limits that keeps the hard geometric constraints could meet it (to first
    order: its rows at the start, the joint box q_lo - q <= dq <= q_hi - q, no rate limits). One that no
    such motion meets is a warning: its slack pulls at the tool every tick, hands off included, and never
    lets go; one that can be met is a note (the controller's slack brings it in over the first ticks)."""
    residuals = Residuals(task, linear.context)
    p = linear.default_params
    hard = [r for r in rows if not r.constraint.soft and not CONSTRAINTS[r.constraint.primitive].rate]
    findings = []
    for r in rows:
        c = r.constraint
        measured = _error(task, r, residuals, q, p) if c.soft else None
        if measured is None:
            continue
        kind, limit, error, _ = measured
        if not _outside(error, limit):
            continue
        short = _shortfall(r, hard, nq)
        level = f"priority {c.priority or 1}"
        what = f"{quantity(limit, kind)} tolerance" if limit > 0 else "boundary"
        data = {"error": error, "limit": limit, "priority": c.priority or 1,
                "short": short, "meetable": short is not None and short <= SHORT}
        figures.setdefault("soft_at_start", {})[where(c)] = data
        if short is None:
            continue                                   # the hard rows themselves conflict: VF301 says so
        if short > SHORT:
            findings.append(Finding(
                "soft-unmet-at-start", Severity.WARNING,
                f"this soft constraint ({level}) cannot be met at the start: its error is {quantity(error, kind)} "
                f"against its {what}, and no motion within the joint limits that keeps the hard constraints "
                f"meets it (to first order it stays {quantity(short, kind)} short): its slack pulls at the tool "
                f"every tick, with the hands off too", c.span,
                "move the reference within reach, or make it a lower priority or a hard constraint's job",
                subject(c), data))
        else:
            findings.append(Finding(
                "soft-unmet-at-start", Severity.NOTE,
                f"this soft constraint ({level}) does not hold at the start: its error is {quantity(error, kind)} "
                f"against its {what}; a motion within the joint limits meets it, and its slack pulls the tool "
                f"there over the first ticks, with the hands off too", c.span,
                "start inside its tolerance if the tool should stay still", subject(c), data))
    return findings


SHORT = 1e-9                     # m or rad: a first-order shortfall above this is "cannot be met"


def _shortfall(r: ConstraintRows, hard: list[ConstraintRows], nq: int) -> float | None:
    """min s >= 0 such that r's rows hold within s while every hard row and the joint box hold exactly
    (an LP over [dq, s]); None when the hard rows alone cannot hold."""
    from scipy.optimize import linprog

    from vfdsl.check.lp import _HIGHS, LinearSystem

    system = LinearSystem.from_rows(hard, nq)
    if np.any(system.lo > system.hi):
        return None
    blocks, bounds = [], []
    for A, lb, ub, slack in ((system.A, system.lb, system.ub, 0.0), (r.A, r.lb, r.ub, 1.0)):
        low, up = np.isfinite(lb), np.isfinite(ub)
        blocks.append(np.hstack([-A[low], -slack * np.ones((low.sum(), 1))]))     # -a dq - s <= -lb
        bounds.append(-lb[low])
        blocks.append(np.hstack([A[up], -slack * np.ones((up.sum(), 1))]))        #  a dq - s <= ub
        bounds.append(ub[up])
    A_ub, b_ub = np.vstack(blocks), np.concatenate(bounds)
    box = [(None if not np.isfinite(a) else a, None if not np.isfinite(b) else b)
           for a, b in zip(system.lo, system.hi)]
    c = np.zeros(nq + 1)
    c[-1] = 1.0
    result = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=box + [(0, None)], method="highs", options=_HIGHS)
    if result.status != 0:
        return None
    return float(result.x[-1])
