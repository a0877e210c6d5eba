"""A port close to the tracked point: how fast can the tool still move that point sideways?

``passes_through(port)`` keeps the tool's axis line through a point c. To move a tracked point p (the origin
of a frame a ``track`` term drives with a linear command; usually the tool tip on that axis) sideways at a
speed v, the tool has to turn about the port: p then moves as a point of a body pivoting about c, so
v = |w x (p - c)| <= |w| L with the lever L = |p - c|, and the tool turns at least

    |w| >= v / L          (1 / L rad/s per m/s: 0.5 rad/s per mm/s at L = 2 mm).

Whether the joints can turn it that fast is a linear program in the joint rates qdot at the start q0: the
fastest sideways speed s along a unit direction u normal to the tool axis,

    s(u) = max s   subject to   J_v qdot = s u                 (the point moves along u only)
                                A qdot = 0                     (the port's rows: the axis stays on c)
                                |qdot_k| <= f qdot_max_k       (joint speed limits)

with J_v the tracked frame's Jacobian (Pinocchio), A the port's rows as the compiler lowers them, qdot_max
the URDF limits and f the task's hard ``joint_speed`` fraction (1 without one: the robot's own limits still
hold). It is solved (HiGHS) for DIRECTIONS directions over a half-turn (s(-u) = s(u)); the slowest, s_port,
exceeds the slowest over all directions by at most 1 / cos(pi / (2 DIRECTIONS)) - 1 (0.2 %). The program is
homogeneous: moving the point sideways at 1 mm/s takes at least (1 mm/s) / s_port of a joint's speed limit.
The joint named is the one whose limit binds most (its dual value times its limit). Without the port's rows
the same program gives s_free, what the robot does without the port.

VF605 port-lever-short (warning) when both hold:

- s_port < REFERENCE_SPEED: a hand moving the tool sideways at the speed up to which the check's sampled
  analysis drives a tracked frame (20 mm/s) is cut; equivalently, 1 mm/s sideways takes more than 5 % of a
  joint's speed limit;
- s_port < s_free / 2: the port, not the robot's own speed, cuts the motion (at least by half).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from vfdsl.check.kinematics import frame_jacobian, frame_pose
from vfdsl.check.linearized import ConstraintRows, Linearization
from vfdsl.check.lp import linprog
from vfdsl.ir.constraints import describe, subject, value_of, where
from vfdsl.check.report import Finding, Severity, quantity
from vfdsl.check.sampling import SAMPLE_SPEED
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import flag

REFERENCE_SPEED = SAMPLE_SPEED   # m/s
PORT_SHARE = 0.5                 # warn when the port leaves at most this share of the robot's own sideways speed
DIRECTIONS = 24                  # sideways directions over a half-turn


def tracked(task: ir.Task) -> list[ir.Objective]:
    """The ``track`` terms that command a linear velocity: a force, wrench or twist input, a gain, linear on."""
    return [o for o in task.objectives
            if o.term == "track" and "gain" in o.args and flag(o.args, "linear")
            and INPUT_TYPES[task.input(o.args["input"].name).type].linear]


def speed_limits(task: ir.Task, robot) -> np.ndarray:
    """Each joint's speed limit: the URDF's, times the smallest hard ``joint_speed`` fraction of the task."""
    fractions = [value_of(c.args["fraction"], task).value for c in task.constraints
                 if c.primitive == "joint_speed" and not c.soft]
    return min(fractions, default=1.0) * robot.velocity_limit


def fastest(Jv: np.ndarray, held: np.ndarray, limits: np.ndarray, u: np.ndarray) -> tuple[float, np.ndarray]:
    """max s with Jv qdot = s u, held qdot = 0 and |qdot| <= limits; (s, how much each joint's limit binds:
    the gain in s per unit relative increase of that limit)."""
    nq = len(limits)
    A_eq = np.vstack([np.hstack([Jv, -u[:, None]]), np.hstack([held, np.zeros((len(held), 1))])])
    cost = np.zeros(nq + 1)
    cost[-1] = -1.0
    result = linprog(cost, A_eq=A_eq, b_eq=np.zeros(len(A_eq)), bounds=[(-v, v) for v in limits] + [(0, None)],
                     method="highs")
    if result.status != 0:          # cannot happen: qdot = 0, s = 0 is feasible and the box bounds s
        raise RuntimeError(f"sideways-speed LP failed: {result.message}")
    binding = (np.abs(result.lower.marginals[:nq]) + np.abs(result.upper.marginals[:nq])) * limits
    return float(result.x[-1]), binding


def slowest(Jv: np.ndarray, held: np.ndarray, limits: np.ndarray, axis: np.ndarray):
    """The slowest sideways direction normal to ``axis``: (speed, direction, binding per joint)."""
    a = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(axis, a)
    found = []
    for angle in np.pi * np.arange(DIRECTIONS) / DIRECTIONS:
        u = np.cos(angle) * a + np.sin(angle) * b
        found.append((*fastest(Jv, held, limits, u), u))
    speed, binding, u = min(found, key=lambda item: item[0])
    return speed, u, binding


def _row_space(A: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the rows' span (the port's n facet rows span 2 directions)."""
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    return Vt[:int(np.sum(s > 1e-9 * s[0]))] if len(s) and s[0] > 0 else np.zeros((0, A.shape[1]))


def _input_limit(task: ir.Task, o: ir.Objective, speed: float) -> str:
    """The sideways input beyond which the motion is cut, at the term's gain: 'a push above 11.3 N at ...'."""
    gain = abs(value_of(o.args["gain"], task).value)
    if INPUT_TYPES[task.input(o.args["input"].name).type].linear.rate:
        return f"a sideways command above {quantity(speed / gain, 'speed')} at the track term's gain of {gain:.3g}"
    return f"a sideways push above {speed / gain:.3g} N at the track term's gain of {gain * 1e3:.3g} mm/s/N"


def _per(a: float, b: float) -> float:
    return a / b if b > 0 else np.inf


def analyse(task: ir.Task, linear: Linearization, rows: list[ConstraintRows], q, figures: dict) -> list[Finding]:
    robot, ctx = linear.robot, linear.context
    limits = speed_limits(task, robot)
    findings = []
    for r in rows:
        c = r.constraint
        if c.primitive != "passes_through" or c.soft:
            continue
        port = np.array(ca.Function("port", [ctx.q, ctx.u, ctx.p, ctx.dt], [ctx.point(c.args["port"])])(
            q, np.zeros(linear.n_inputs), linear.default_params, linear.period)).ravel()
        constrained = task.frame(c.frame)
        axis = frame_pose(robot, constrained, q)[1] @ np.asarray(constrained.tool_axis)
        held = _row_space(r.A)
        for o in tracked(task):
            point = task.frame(o.args["frame"].name)
            Jv = frame_jacobian(robot, point, q)[:3]
            lever = float(np.linalg.norm(port - frame_pose(robot, point, q)[0]))
            speed, u, binding = slowest(Jv, held, limits, axis)
            free = slowest(Jv, np.zeros((0, robot.nq)), limits, axis)[0]
            k = int(np.argmax(binding))
            data = {"tracked": point.name, "lever": lever, "pivot_rate": _per(1.0, lever), "sideways_speed": speed,
                    "free_speed": free, "reference_speed": REFERENCE_SPEED, "joint": robot.joint_names[k],
                    "joint_limit": float(limits[k]), "direction": u.tolist()}
            figures.setdefault("levers", {})[f"{describe(c)} at {where(c)} -> {point.name}"] = data
            if not (speed < REFERENCE_SPEED and speed < PORT_SHARE * free):
                continue
            limit = (quantity(limits[k], "speed") if robot.joint_types[k] == "prismatic"
                     else f"{limits[k]:.3g} rad/s")
            message = (f"the port is {quantity(lever, 'length')} from the tracked point '{point.name}': moving it "
                       f"sideways at 1 mm/s turns the tool about the port at {_per(1.0, lever) * 1e-3:.3g} rad/s, "
                       f"and within the joint speed limits it moves sideways at most {quantity(speed, 'speed')} "
                       f"({_per(speed, lever):.3g} mm/s per mm of lever; 1 mm/s takes {_per(1e-3, speed):.1%} of "
                       f"{robot.joint_names[k]}'s limit of {limit}), against {quantity(free, 'speed')} without the "
                       f"port: {_input_limit(task, o, speed)} is cut")
            hint = (f"move the port farther from '{point.name}' (the sideways speed grows about in proportion to the "
                    f"lever: about {quantity(lever * _per(REFERENCE_SPEED, speed), 'length')} for "
                    f"{quantity(REFERENCE_SPEED, 'speed')}), or accept the reduced motion; `vfdsl simulate` reports "
                    f"the fraction of the commanded motion made")
            findings.append(Finding("port-lever-short", Severity.WARNING, message, c.span, hint, subject(c), data))
    return findings
