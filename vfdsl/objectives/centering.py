"""Joint centering:  weight * sum_i ((q_i + dq_i - c_i) / r_i)^2, c_i the middle and r_i the half range of
joint i's limits (joints without limits are skipped): keeps joints away from their limits."""

import casadi as ca
import numpy as np

from vfdsl.compiler.rows import Term
from vfdsl.primitives.spec import ObjectiveSpec

SPEC = ObjectiveSpec(name="centering", summary="pull joints toward the middle of their range")


def lower(o, ctx) -> Term:
    robot = ctx.robot
    limited = [i for i in range(robot.nq) if np.isfinite(robot.lower[i]) and np.isfinite(robot.upper[i])]
    middle = (robot.lower[limited] + robot.upper[limited]) / 2
    half_range = (robot.upper[limited] - robot.lower[limited]) / 2
    E = ca.SX(ca.DM(np.eye(robot.nq)[limited, :] / half_range[:, None]))
    return Term(E=E, f=(ca.DM(middle) - ctx.q[limited]) / ca.DM(half_range))
