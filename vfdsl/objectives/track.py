"""Track the user's input (paper II-C, eq. 18; admittance control), as rates:

    linear part:   weight * || J_v dq/dt - v_d ||^2     (m/s)
    angular part:  weight * || J_w dq/dt - w_d ||^2     (rad/s)

v_d = gain f and w_d = angular_gain tau for a wrench [f; tau] (a force gives only f, a torque only tau; a part the
input does not drive is asked to stay still: v_d = 0 or w_d = 0), or v_d = gain v, w_d = angular_gain w for a twist.

The two parts are solved one after the other: the part the input drives first, then the other among the motions
that keep the first optimal (a priority step just below the statement's level): for a force, a wrench or a twist
the linear part first, for a torque the angular part first. So the frame follows the hand even when a constraint
couples translation and rotation (a port, a cone, a remote center: the tool has to pivot to move its tip
sideways, or its tip has to move to turn the tool about a remote point), and with the hands off both parts ask
for no motion, so the frame stays still.

- ``linear = false`` / ``angular = false`` leaves that part free (not tracked at all);
- ``lever = L`` solves both parts together instead, on one level, the angular rate error weighing as the speed
  error of a point at distance L: weight * (|| J_v dq/dt - v_d ||^2 + L^2 || J_w dq/dt - w_d ||^2).
"""

import functools

import casadi as ca

from vfdsl.compiler.rows import Term
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import GAIN, SIZE, ArgSpec, ObjectiveSpec, flag

SPEC = ObjectiveSpec(
    name="track",
    summary="move the frame as the input commands (admittance: velocity = gain * input)",
    args=(ArgSpec("frame", "frame", "the task frame that follows the input"),
          ArgSpec("input", "input", "the user's force, torque, wrench or twist"),
          ArgSpec("gain", "gain", "linear admittance (m/s per N, or a scale for a twist)", default=None,
                  range=GAIN),
          ArgSpec("angular_gain", "angular_gain", "angular admittance (rad/s per N m, or a scale)",
                  default=None, range=GAIN),
          ArgSpec("linear", "flag", "track the frame's linear velocity (false: leave it free)",
                  default=ir.FlagValue(value=True)),
          ArgSpec("angular", "flag", "track the frame's angular velocity (false: leave it free)",
                  default=ir.FlagValue(value=True)),
          ArgSpec("lever", "length", "solve both parts on one level, an angular error weighing as the speed "
                  "error of a point this far away", default=None, range=SIZE)),
    source="Li, Kapoor & Taylor 2005, II-C, eq. (18)",
)


@functools.cache
def commanded_motion(input_type: str) -> ca.Function:
    """(u, gain, angular_gain) -> (v_d, w_d): the linear and angular velocity an input of ``input_type`` asks for,
    gain times its linear part and angular_gain times its angular part (zero for a part it does not drive)."""
    kind = INPUT_TYPES[input_type]
    u = ca.SX.sym("u", kind.size)
    gain, angular_gain = ca.SX.sym("gain"), ca.SX.sym("angular_gain")
    v_d = gain * u[kind.linear_range] if kind.linear else ca.SX.zeros(3)
    w_d = angular_gain * u[kind.angular_range] if kind.angular else ca.SX.zeros(3)
    return ca.Function(f"commanded_{input_type}", [u, gain, angular_gain], [v_d, w_d],
                       ["u", "gain", "angular_gain"], ["v_d", "w_d"])


def commanded(o, ctx) -> tuple[ca.SX, ca.SX]:
    """(v_d, w_d) of the term: :func:`commanded_motion` on its input and gains."""
    gain = ctx.scalar(o.args["gain"]) if "gain" in o.args else 0.0
    angular_gain = ctx.scalar(o.args["angular_gain"]) if "angular_gain" in o.args else 0.0
    return commanded_motion(ctx.task.input(o.args["input"].name).type)(ctx.input(o.args["input"]), gain, angular_gain)


def lower(o, ctx) -> tuple[Term, ...]:
    f = ctx.frame(o.args["frame"].name)
    v_d, w_d = commanded(o, ctx)
    linear, angular = flag(o.args, "linear"), flag(o.args, "angular")
    if "lever" in o.args:
        lever = ctx.scalar(o.args["lever"])
        parts = [(f.Jv, v_d)] * linear + [(lever * f.Jw, lever * w_d)] * angular
        return (Term(E=ca.vertcat(*(E for E, _ in parts)), f=ca.vertcat(*(r for _, r in parts)), part="twist"),)
    parts = [Term(E=f.Jv, f=v_d, part="linear")] * linear + [Term(E=f.Jw, f=w_d, part="angular")] * angular
    if not INPUT_TYPES[ctx.task.input(o.args["input"].name).type].linear:
        parts.reverse()                 # the driven part first
    return tuple(Term(t.E, t.f, t.part, after=k) for k, t in enumerate(parts))
