"""Joint centering:  weight * sum_i ((dq_i/dt - (c_i - q_i)/tau) / r_i)^2, c_i the middle and r_i the half range
of joint i's limits (joints without limits are skipped), tau the time constant: keeps joints away from their limits,
at a rate in 1/s (half ranges per second). A redundancy term: by default it acts below the task terms, in the
motions that leave them optimal."""

import casadi as ca
import numpy as np

from vfdsl.compiler.rows import Term, toward
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import POSITIVE, REDUNDANCY_LEVEL, ArgSpec, ObjectiveSpec

SPEC = ObjectiveSpec(
    name="centering",
    summary="pull joints toward the middle of their range",
    args=(ArgSpec("time_constant", "time", "how fast a joint is pulled to its middle (error / time_constant)",
                  default=ir.ScalarValue(dimension="time", value=1.0), range=POSITIVE),),
    priority=REDUNDANCY_LEVEL,
)


def lower(o, ctx) -> tuple[Term]:
    robot = ctx.robot
    limited = [i for i in range(robot.nq) if np.isfinite(robot.lower[i]) and np.isfinite(robot.upper[i])]
    middle = (robot.lower[limited] + robot.upper[limited]) / 2
    half_range = ca.DM((robot.upper[limited] - robot.lower[limited]) / 2)
    E = ca.SX(ca.DM(np.eye(robot.nq)[limited, :])) / ca.repmat(half_range, 1, robot.nq)
    rate = toward(ca.DM(middle) - ctx.q[limited], ctx.scalar(o.args["time_constant"]), ctx.dt)
    return (Term(E=E, f=rate / half_range),)
