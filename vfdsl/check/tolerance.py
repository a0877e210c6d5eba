"""Tolerances: positive, of a plausible size, realizable by the joints, and restorable within a tick.

- **Sign and size.** The front end checks a tolerance's dimension (length or angle) and sign in the file;
  here a tolerance built in Python is checked again, and a size outside [0.1 um, 20 mm] (lengths) or
  [1 urad, 20 deg] (angles) is flagged as a likely unit slip.
- **Joint resolution.** With joint steps of res_k (the robot's sidecar), the frame can be placed along a
  facet row a (a = -u J, one row of the constraint at the start) only to within half a step of each
  joint: q_res = 1/2 max_rows sum_k |a_k| res_k. A tolerance below q_res cannot be realized.
- **Restore time.** The joint speeds and the frames' speed limits bound one tick's motion; the reach
  along a facet row is s_i = max a_i dq over those rate rows (an LP). Undoing a deviation of one
  tolerance takes ceil(eps / min_i s_i) ticks: a note from 2 ticks, a warning above SLOW_RESTORE_TICKS.
  The finding names the rate limits that cause it: those whose removal lets the worst row reach at
  least twice as far.
- **Speed limits** (VF205). A speed, angular speed or joint_speed fraction outside PLAUSIBLE_SPEED is
  most likely a unit slip: too slow and hard, an error; otherwise a warning.
"""

from __future__ import annotations

import math

import numpy as np

from vfdsl.check.linearized import ConstraintRows
from vfdsl.ir.constraints import subject, value_of, where
from vfdsl.check.lp import LinearSystem
from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.errors import a_or_an
from vfdsl.ir import model as ir
from vfdsl.primitives import CONSTRAINTS

PLAUSIBLE = {"length": (1e-7, 0.02), "angle": (1e-6, math.radians(20))}
# Speed limits (VF205): slower than the low end, a correction of a millimetre (a degree) takes minutes;
# faster than the high end, the limit binds no surgical robot. Either is most likely a unit slip.
PLAUSIBLE_SPEED = {"speed": (1e-5, 5.0),                                  # 10 um/s .. 5 m/s
                   "angular_speed": (math.radians(0.01), math.radians(1000)),   # 0.01 .. 1000 deg/s
                   "number": (1e-3, 1.0)}                                 # joint_speed's fraction of the URDF's
SLOW_RESTORE_TICKS = 10      # a restore slower than this many ticks is a warning; 2..10 ticks a note


def analyse_values(task: ir.Task) -> list[Finding]:
    """Sign and size of every tolerance (needs no robot state)."""
    findings = []
    for c in task.constraints:
        if c.tolerance is None:
            continue
        kind = CONSTRAINTS[c.primitive].tolerance
        eps = c.tolerance
        heading = subject(c)
        if not math.isfinite(eps) or eps <= 0:
            findings.append(Finding("tolerance-nonpositive", Severity.ERROR,
                                    f"the tolerance is {eps!r}: it must be a positive, finite {kind}", c.span,
                                    "write `within <a positive value>`", heading, {"tolerance": eps}))
            continue
        low, high = PLAUSIBLE[kind]
        if not low <= eps <= high:
            side = "below" if eps < low else "above"
            findings.append(Finding(
                "tolerance-implausible", Severity.WARNING,
                f"a tolerance of {quantity(eps, kind)} is {side} the plausible range "
                f"[{quantity(low, kind)}, {quantity(high, kind)}] for {a_or_an(kind)}: "
                "a unit slip?", c.span,
                "give the unit explicitly, e.g. `within 0.5 mm` or `within 1 deg`", heading,
                {"tolerance": eps, "range": [low, high]}))
    return findings


def analyse_speeds(task: ir.Task) -> list[Finding]:
    """VF205: a speed limit (speed, angular_speed, joint_speed's fraction) outside its plausible range.
    Too slow and hard: an error (the fixture cannot correct in any useful time); too slow and soft, or too
    fast: a warning."""
    findings = []
    for c in task.constraints:
        if c.primitive not in ("speed", "angular_speed", "joint_speed"):
            continue
        key = "fraction" if c.primitive == "joint_speed" else "max"
        if key not in c.args:
            continue                              # joint_speed's default fraction, 1
        value = value_of(c.args[key], task)
        stated = float(value.value)
        kind = "number" if c.primitive == "joint_speed" else c.primitive
        low, high = PLAUSIBLE_SPEED[kind]
        if low <= stated <= high:
            continue
        slow = stated < low
        text = (f"fraction = {stated:g} of the URDF velocity limits" if kind == "number"
                else f"a limit of {quantity(stated, kind)}")
        if kind == "number":
            effect = "no joint may move faster than that fraction of its rated speed"
            hint = "a fraction such as 0.5 (half the URDF velocity limits); VF204 gives the correction times"
        elif slow:
            effect = (f"at it a correction of 1 {'mm' if kind == 'speed' else 'deg'} takes "
                      f"{(1e-3 if kind == 'speed' else math.radians(1)) / stated:.3g} s")
            hint = "give the unit explicitly, e.g. `speed(5 mm/s)` or `angular_speed(10 deg/s)`"
        else:
            effect = "no surgical robot moves that fast: the limit binds nothing"
            hint = "give the unit explicitly, e.g. `speed(5 mm/s)` or `angular_speed(10 deg/s)`"
        unit = ("" if kind == "number" else f" [{quantity(low, kind)}, {quantity(high, kind)}]")
        findings.append(Finding(
            "speed-implausible", Severity.ERROR if slow and not c.soft else Severity.WARNING,
            f"{text} is {'below' if slow else 'above'} the plausible range{unit or f' [{low:g}, {high:g}]'}: "
            f"{effect}; {'a slip' if kind == 'number' else 'a unit slip'}?", c.span, hint, subject(c),
            {"stated": stated, "range": [low, high], "slow": slow}))
    return findings


def realizable(rows: ConstraintRows, resolution: np.ndarray) -> float:
    """Half a step of every joint, summed along the worst facet row: how finely the joints place the frame."""
    return float(0.5 * np.max(np.abs(rows.A) @ resolution))


def one_tick_reach(rows: ConstraintRows, rates: LinearSystem) -> float:
    """The smallest, over the facet rows, of how far one tick can move along that row at the rate limits."""
    return min(rates.reach(a) for a in rows.A)


def limiting_rates(rows: ConstraintRows, rate_rows: list[ConstraintRows], nq: int, reach: float
                   ) -> list[ConstraintRows]:
    """The rate limits that make one tick's reach along the worst facet row of ``rows`` so small: each one
    whose removal (the others kept) lets that row reach at least twice as far, most limiting first."""
    worst = min(rows.A, key=lambda a: LinearSystem.from_rows(rate_rows, nq).reach(a))
    gains = []
    for k, rate in enumerate(rate_rows):
        rest = rate_rows[:k] + rate_rows[k + 1:]
        freed = LinearSystem.from_rows(rest, nq).reach(worst) if rest else math.inf
        if freed >= 2 * reach:
            gains.append((freed, k, rate))
    return [rate for _, _, rate in sorted(gains, key=lambda g: (-g[0], g[1]))]


def describe_limit(c: ir.Constraint) -> str:
    """A rate limit with its value: ``speed(tip) of 1 um/s``, ``joint_speed(fraction = 1e-05)``."""
    if c.primitive == "joint_speed":
        fraction = c.args.get("fraction")
        return f"joint_speed(fraction = {_number(fraction)})"
    if "max" in c.args and isinstance(c.args["max"], ir.Const):
        return f"{c.primitive}({c.frame}) of {quantity(float(c.args['max'].value.value), c.primitive)}"
    return f"{c.primitive}({c.frame or ''})"


def _number(arg) -> str:
    if arg is None:
        return "1"
    return f"{float(arg.value.value):g}" if isinstance(arg, ir.Const) else arg.name


def analyse_at_start(rows: list[ConstraintRows], resolution: np.ndarray | None, nq: int, period: float,
                     figures: dict | None = None) -> list[Finding]:
    """VF203 and VF204 at the start; ``figures["reach_per_tick"]`` gets each constraint's one-tick reach (by its
    line, :func:`where`), which a procedure's entry funnels (VF956) are measured against."""
    findings = []
    rate_rows = [r for r in rows if CONSTRAINTS[r.constraint.primitive].rate and not r.constraint.soft]
    rates = LinearSystem.from_rows(rate_rows, nq) if rate_rows else None
    for r in rows:
        c = r.constraint
        if c.tolerance is None or not c.tolerance > 0 or not len(r.A):
            continue
        kind = CONSTRAINTS[c.primitive].tolerance
        eps = c.tolerance
        heading = subject(c)
        if resolution is not None:
            finest = realizable(r, resolution)
            if eps < finest:
                findings.append(Finding(
                    "tolerance-below-resolution", Severity.WARNING,
                    f"the tolerance {quantity(eps, kind)} is finer than the {quantity(finest, kind)} to which "
                    f"the joints' resolution can place the frame along this constraint at the start "
                    f"(half a step of each joint, summed)", c.span,
                    f"a tolerance of at least {quantity(finest, kind)} is realizable on this robot",
                    heading, {"tolerance": eps, "realizable": finest}))
        if rates is not None:
            reach = one_tick_reach(r, rates)
            if figures is not None:
                figures.setdefault("reach_per_tick", {})[where(c)] = reach
            if 0 < reach < eps:
                ticks = math.ceil(eps / reach)
                limits = limiting_rates(r, rate_rows, nq, reach)
                named = [f"{describe_limit(x.constraint)} at {where(x.constraint)}" for x in limits]
                cause = f"; the limit: {' and '.join(named)}" if named else ""
                findings.append(Finding(
                    "tolerance-restore-ticks", Severity.WARNING if ticks > SLOW_RESTORE_TICKS else Severity.NOTE,
                    f"at the speed limits one tick ({quantity(period, 'time')}) moves only {quantity(reach, kind)} "
                    f"along this constraint's worst facet: undoing a deviation of one tolerance "
                    f"({quantity(eps, kind)}) takes {ticks} ticks ({ticks * period:.3g} s){cause}", c.span,
                    (f"raise {named[0]}, or shorten the period" if named else
                     "raise the joint_speed fraction or the speed limits, or shorten the period"), heading,
                    {"tolerance": eps, "reach_per_tick": reach, "ticks": ticks, "period": period,
                     "limited_by": [where(x.constraint) for x in limits]}))
    return findings
