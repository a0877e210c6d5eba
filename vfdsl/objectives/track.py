"""Track the user's input (paper II-C, eq. 18; admittance control).

The frame's twist follows the input through the admittance law: dx_d = K u dt with
K = diag(gain I3, angular_gain I3) acting on a wrench [f; tau] (a force drives only translation, a torque
only rotation, the other part is asked to stay still), or K = gain for a twist input. Term:
weight * || J_f dq - dx_d ||^2.
"""

import casadi as ca

from vfdsl.compiler.rows import Term
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ObjectiveSpec

SPEC = ObjectiveSpec(
    name="track",
    summary="move the frame as the input commands (admittance: velocity = gain * input)",
    args=(ArgSpec("frame", "frame", "the task frame that follows the input"),
          ArgSpec("input", "input", "the user's force, torque, wrench or twist"),
          ArgSpec("gain", "gain", "linear admittance (m/s per N, or a scale for a twist)", default=None,
                  range=POSITIVE),
          ArgSpec("angular_gain", "angular_gain", "angular admittance (rad/s per N m, or a scale)",
                  default=None, range=POSITIVE)),
    source="Li, Kapoor & Taylor 2005, II-C, eq. (18)",
)


def lower(o, ctx) -> Term:
    f = ctx.frame(o.args["frame"].name)
    u = ctx.input(o.args["input"])
    kind = ctx.task.input(o.args["input"].name).type
    gain = ctx.scalar(o.args["gain"]) if "gain" in o.args else 0.0
    angular_gain = ctx.scalar(o.args["angular_gain"]) if "angular_gain" in o.args else 0.0
    if kind == "force":
        linear, angular = u, ca.DM.zeros(3)
    elif kind == "torque":
        linear, angular = ca.DM.zeros(3), u
    else:
        linear, angular = u[0:3], u[3:6]
    return Term(E=f.J, f=ca.vertcat(gain * linear, angular_gain * angular) * ctx.dt)
