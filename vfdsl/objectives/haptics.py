"""What a teleoperated tick gives back beside dq (DESIGN, "Procedures and teleoperation"): the haptic force on the
master, the slave's Cartesian set-point, whether the master is followed, and which constraint rows acted.

One Function ``teleop_readout(q, u, p, dt[, activity], x, state) -> (force, setpoint, goal, depth, following, acting, next_state)``
after the tick's solve x = [dq; slack]. For each `teleop` term (objectives/teleop.py), with its frame's twist
Jacobian J (6 x n), the rates it commands c = [v_c; w_c], its tau and its phase weight w (1 outside phases):

    acting rows      i with a_i x within ACTING of lba_i or uba_i, or beyond (a least-violation tick)
    their normals    n_i = (J J' + LAMBDA I)^-1 J a_i        the twist whose pull-back onto the joints is the row's
                                                             dq part (exact for a square regular J)
    M                sum over the acting rows of n_i n_i' / |n_i|^2
    removed twist    r = c - J dq / dt                        what the fixtures took from the command this tick,
                                                             predicted through J dq (not the lagging measured pose)
    withheld         d_s = tau [M (M + EPS I)^-1 r]_linear    (m) the part of the goal's gap the acting rows hold back,
                                                             along their normals only
    on the master    d_m = R_c' d_s / scale                   (m) the master's motion those rows stopped
    engaged          t_e = t_e + dt while w > 1/2, else 0     (s) how long the master has been followed
    spring-damper    s = -(k d_m + b (d_m - d_prev) / dt)   (no damping at the first tick)
    one-sided        s' = s - max(0, s.d_m) d_m / |d_m|^2,  0 where d_m = 0   a wall pushes the master out, never
                                                             pulls it in (withdrawing, or at the tick contact ends)
    target           F* = min(1, t_e / ramp) sat(s', F_max)
    force            F = F_prev + clip(F* - F_prev, rate dt)  (N, in the master's base frame)

so free motion (no acting row) feels nothing, whatever the tracking lag, and a wall feels k times the master's
depth past it, along its normal. The force ramps in over ``ramp`` after engage (and to 0 while clutched); the rate
limit smooths whatever is left. ``state`` = [d_prev (3), F_prev (3), warm (1), t_e (1)] per term, zeros before the
first tick.

The set-point is the first teleop frame's pose after dq, [p; roll, pitch, yaw] (exact kinematics at q + dq): what a
robot driven by pose is sent; the goal is that term's g (where the scaled master puts the frame: its ghost), the
depth its d_m (how far the master is past the acting rows, in its base frame). ``following`` is the largest phase weight of the teleop terms (1: following; 0:
clutched or disabled).
"""

from __future__ import annotations

import casadi as ca

from vfdsl.codegen import tick_buffers
from vfdsl.compiler.assemble import AssembledProblem
from vfdsl.compiler.geometry import rpy_of
from vfdsl.compiler.phases import gated_statements
from vfdsl.ir import model as ir
from vfdsl.objectives import teleop

ACTING = 1e-9
"""A row acts when its value at x is within this of a bound (m, rad per tick: the solver's answers sit at 1e-12)."""
LAMBDA = 1e-10
"""Regularization of J J' when mapping a row onto the frame's twists (J J' is ~1e-2..1 on the built-in robots)."""
EPS = 1e-6
"""Regularization of the projection onto the acting normals: directions M weighs below EPS (nearly parallel rows) are
let go smoothly instead of amplified."""
STATE = 8
"""State numbers per teleop term: the previous master depth (3), the previous force (3), warm (1), engaged time (1)."""
READOUT = ("force", "setpoint", "goal", "depth", "following", "acting", "next_state")


def teleop_terms(task: ir.Task) -> list[ir.Objective]:
    """Every `teleop` term of the task, outside phases then phase by phase (the readout's state order)."""
    return [o for o in task.every_objective if o.term == "teleop"]


def readout_function(task: ir.Task, problem: AssembledProblem) -> ca.Function | None:
    """The task's ``teleop_readout`` (module docstring), or None without a teleop term."""
    ctx = problem.context
    _, objectives = gated_statements(task, ctx)
    terms = [(o, gate) for o, gate in objectives if o.term == "teleop"]
    if not terms:
        return None
    nq, n = problem.nq, problem.nq + problem.n_slack
    arguments = [getattr(ctx, name) for name in tick_buffers.data_arguments(bool(task.phases))]
    x = ca.SX.sym("x", n)
    state = ca.SX.sym("state", STATE * len(terms))
    _, _, A, lba, uba, *_ = problem.function(*arguments)       # the rows, as the step builds them
    Ax = A @ x
    acting = ca.logic_or(Ax - lba <= ACTING, uba - Ax <= ACTING)
    A_q = A[:, :nq]
    dq, dt = x[:nq], ctx.dt
    force, new_state, weights = ca.SX.zeros(3), [], []
    for k, (o, gate) in enumerate(terms):
        frame = ctx.frame(o.args["frame"].name)
        J = ca.vertcat(frame.Jv, frame.Jw)
        v_c, w_c, tau = teleop.commanded(o, ctx)
        normals = ca.solve(J @ J.T + LAMBDA * ca.SX.eye(6), J @ A_q.T)            # 6 x m
        lengths = ca.sum1(normals ** 2)
        M = (normals * ca.repmat(ca.if_else(acting.T, 1 / ca.fmax(lengths, 1e-300), 0), 6, 1)) @ normals.T
        removed = ca.vertcat(v_c, w_c) - J @ dq / dt
        withheld = tau * (M @ ca.solve(M + EPS * ca.SX.eye(6), removed))[:3]
        R_c, _ = ctx.pose(o.args["camera"])
        depth = R_c.T @ withheld / ctx.scalar(o.args["scale"])
        own = state[STATE * k:STATE * (k + 1)]
        previous, F_prev, warm, engaged = own[0:3], own[3:6], own[6], own[7]
        rate = (depth - previous) / dt
        spring = _one_sided(-(ctx.scalar(o.args["stiffness"]) * depth + warm * ctx.scalar(o.args["damping"]) * rate),
                            depth)
        weight = 1 if gate.weight is None else gate.weight
        engaged = ca.if_else(weight > 0.5, engaged + dt, 0)
        target = ca.fmin(1, engaged / ctx.scalar(o.args["ramp"])) * _saturated(spring, ctx.scalar(o.args["saturation"]))
        F = F_prev + _saturated(target - F_prev, ctx.scalar(o.args["rate_limit"]) * dt)
        force += F
        new_state += [depth, F, ca.DM(1), engaged]
        weights.append(weight)
    g, _ = teleop.goal(terms[0][0], ctx)
    frame = ctx.frame(terms[0][0].args["frame"].name)
    setpoint = ca.Function("pose", [ctx.q], [ca.vertcat(frame.p, rpy_of(frame.R))])(ctx.q + dq)
    outputs = [force, setpoint, g, new_state[0], ca.mmax(ca.vertcat(*weights)), acting, ca.vertcat(*new_state)]
    # dense: without a constraint row (a teleop task with only joint bounds) the depth and force are structural zeros
    return ca.Function("teleop_readout", [*arguments, x, state], [ca.densify(ca.SX(v)) for v in outputs],
                       [*tick_buffers.data_arguments(bool(task.phases)), "x", "state"], list(READOUT))


def _one_sided(force, depth):
    """The force without its part along the depth (toward the wall), 0 at depth 0 (no row acts)."""
    squared = ca.dot(depth, depth)
    pull = ca.fmax(0, ca.dot(force, depth)) / ca.fmax(squared, 1e-300)
    return ca.if_else(squared > 0, force - pull * depth, 0)


def _saturated(v, limit):
    """v scaled down to norm ``limit`` when longer."""
    return v * ca.fmin(1, limit / ca.fmax(ca.norm_2(v), 1e-300))
