"""Stay close to a point (lecture, slide 44):  weight * || J_v dq/dt - (P - p) / tau ||^2 (m/s): the frame origin p
moves toward P with time constant tau (never more than the whole gap in one tick)."""

from vfdsl.compiler.rows import Term, toward
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ObjectiveSpec

SPEC = ObjectiveSpec(
    name="distance",
    summary="pull the frame origin toward a point",
    args=(ArgSpec("frame", "frame", "the task frame"), ArgSpec("target", "point", "the goal point"),
          ArgSpec("time_constant", "time", "how fast the gap closes (speed = gap / time_constant)",
                  default=ir.ScalarValue(dimension="time", value=1.0), range=POSITIVE)),
    source="Taylor, lecture notes, slide 44",
)


def lower(o, ctx) -> tuple[Term]:
    f = ctx.frame(o.args["frame"].name)
    rate = toward(ctx.point(o.args["target"]) - f.p, ctx.scalar(o.args["time_constant"]), ctx.dt)
    return (Term(E=f.Jv, f=rate),)
