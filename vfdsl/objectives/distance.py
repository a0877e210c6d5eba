"""Stay close to a point (lecture, slide 44):  weight * || p + J_v dq - P ||^2."""

from vfdsl.compiler.rows import Term
from vfdsl.primitives.spec import ArgSpec, ObjectiveSpec

SPEC = ObjectiveSpec(
    name="distance",
    summary="pull the frame origin toward a point",
    args=(ArgSpec("frame", "frame", "the task frame"), ArgSpec("target", "point", "the goal point")),
    source="Taylor, lecture notes, slide 44",
)


def lower(o, ctx) -> Term:
    f = ctx.frame(o.args["frame"].name)
    return Term(E=f.Jv, f=ctx.point(o.args["target"]) - f.p)
